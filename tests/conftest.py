"""The whole session's network rule (docs/testing.md "Network"): a private namespace when
the session can make one, a clear skip for multicast when it cannot, and a guard that fails
any test sending off loopback outside such a namespace."""

from __future__ import annotations

import sys
from collections.abc import Generator

import pytest

from tests.network import SocketAudit, enter_private_namespace, interfaces, is_private

NO_PRIVATE_NETWORK: str | None = None
"""Why the session runs on the machine's own network (``None``: it has a namespace of its own)."""

AUDIT = SocketAudit()


def pytest_configure(config: pytest.Config) -> None:
    """Before any test: leave the machine's network, then watch every socket of this process."""
    global NO_PRIVATE_NETWORK  # noqa: PLW0603 -- one fact for the whole session
    NO_PRIVATE_NETWORK = enter_private_namespace()
    AUDIT.devices = frozenset(interfaces())
    sys.addaudithook(AUDIT)


def pytest_report_header(config: pytest.Config) -> str:
    if NO_PRIVATE_NETWORK is None:
        return "network: a private namespace, loopback only"
    return f"network: the machine's own ({NO_PRIVATE_NETWORK}); multicast tests skip"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, object, object]:
    """A test whose process bound, connected or sent off loopback fails, naming each socket."""
    AUDIT.take()
    result = yield
    if offences := AUDIT.take():
        pytest.fail(
            "sent off loopback outside a private network namespace: " + "; ".join(offences),
            pytrace=False,
        )
    return result


@pytest.fixture
def private_network() -> None:
    """For tests that multicast (python-can ``udp_multicast``): only in a private namespace,
    so that no frame leaves the machine and no other run hears it; otherwise a skip."""
    if NO_PRIVATE_NETWORK is not None or not is_private():
        pytest.skip(f"udp_multicast needs a private network namespace: {NO_PRIVATE_NETWORK}")
