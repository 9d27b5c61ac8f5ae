"""The whole session's network rule (docs/testing.md "Network"): a private namespace when
the session can make one, a clear skip for multicast when it cannot, and a guard that fails
any test sending off loopback outside such a namespace. And where its files go: in memory,
where the machine has a tmpfs for it (docs/testing.md "Under load")."""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Generator

import pytest

from tests.network import SocketAudit, enter_private_namespace, interfaces, is_private

NO_PRIVATE_NETWORK: str | None = None
"""Why the session runs on the machine's own network (``None``: it has a namespace of its own)."""

AUDIT = SocketAudit()


MEMORY_TEMP_DIR = "/dev/shm"  # noqa: S108 -- a tmpfs on every Debian and Ubuntu


def _in_memory(path: str) -> bool:
    """Whether ``path`` is the mount point of a tmpfs this process can write to."""
    try:
        with open("/proc/self/mounts", encoding="utf-8") as mounts:
            kinds = {fields[1]: fields[2] for line in mounts if len(fields := line.split()) > 2}
    except OSError:
        return False
    return kinds.get(path) == "tmpfs" and os.access(path, os.W_OK)


def pytest_configure(config: pytest.Config) -> None:
    """Before any test: the temporary files in memory, then leave the machine's network and
    watch every socket of this process.

    The tests' files (``tmp_path``, and everything the daemons and simulators they start write:
    the simulated outputs' files, the logs, the records) go to a tmpfs unless ``TMPDIR`` says
    otherwise. A simulated output stands for an enable line, which no disk delays; its file on
    a journaled disk is renamed on the disk's time, unbounded while other processes ``fsync``,
    and a stop would be timed late by the disk's stall, not the daemon's. What a slow disk
    does to the daemon is the system tier's ``slowdisk`` scenario."""
    if "TMPDIR" not in os.environ and _in_memory(MEMORY_TEMP_DIR):
        os.environ["TMPDIR"] = MEMORY_TEMP_DIR  # children too: srcsd, srcs-sim, srcsctl
        tempfile.tempdir = None  # read again from TMPDIR by pytest's tmp_path
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
