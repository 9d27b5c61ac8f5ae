"""The session's network rule (docs/testing.md "Network"): the guard and the namespace."""

from __future__ import annotations

import shutil
import socket
import subprocess

import pytest

from tests import conftest
from tests.network import SocketAudit, interfaces, leaves_machine

MACHINE = frozenset({"lo", "eth0"})  # a namespace with a way off the machine


@pytest.mark.parametrize(
    ("address", "leaves"),
    [
        pytest.param(("239.74.163.77", 43113), True, id="multicast group"),
        pytest.param(("192.0.2.7", 80), True, id="another host"),
        pytest.param(("", 43113), True, id="every address"),
        pytest.param(("0.0.0.0", 43113), True, id="IPv4 wildcard"),  # noqa: S104 -- never bound
        pytest.param(("ff02::1", 43113, 0, 1), True, id="IPv6 multicast"),
        pytest.param(("127.0.0.1", 9), False, id="loopback"),
        pytest.param(("127.5.6.7", 9), False, id="the loopback range"),
        pytest.param(("::1", 9, 0, 0), False, id="IPv6 loopback"),
        pytest.param("/run/srcsd/api.sock", False, id="Unix socket"),
        pytest.param(b"\0abstract", False, id="abstract Unix socket"),
    ],
)
def test_only_loopback_stays_on_the_machine(address: object, leaves: bool) -> None:
    """Outside a private namespace, any IP address but loopback (or a wildcard) leaves."""
    assert leaves_machine(address, MACHINE) is leaves


def test_nothing_leaves_a_namespace_with_only_loopback() -> None:
    """Inside a namespace whose only device is lo, no address can take a packet off it."""
    assert not leaves_machine(("239.74.163.77", 43113), {"lo"})


def test_the_audit_names_each_socket_that_would_leave() -> None:
    """The hook collects the bind, connect and send events that would leave, and only those."""
    audit = SocketAudit(devices=MACHINE)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        audit("socket.bind", (sock, ("", 43113)))
        audit("socket.sendto", (sock, ("127.0.0.1", 9)))
        audit("socket.connect", (sock, ("192.0.2.7", 80)))
        audit("socket.__new__", (sock, socket.AF_INET, socket.SOCK_DGRAM, 0))
    assert audit.take() == ["socket.bind ('', 43113)", "socket.connect ('192.0.2.7', 80)"]
    assert audit.take() == []


def test_the_session_has_a_network_of_its_own_when_it_can() -> None:
    """Run as root, the session's only device is lo, up, with multicast routed to it."""
    if conftest.NO_PRIVATE_NETWORK is not None:
        pytest.skip(f"no private namespace here: {conftest.NO_PRIVATE_NETWORK}")
    assert interfaces() == {"lo"}
    ip = shutil.which("ip")
    assert ip is not None
    route = subprocess.run(
        [ip, "route", "show", "224.0.0.0/4"], capture_output=True, text=True, check=True
    )
    assert "dev lo" in route.stdout
