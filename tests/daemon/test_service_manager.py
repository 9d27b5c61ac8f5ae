"""The loop's face to the service manager, on a real datagram socket, time passed as ``now``
(SR-0.2, SR-6.5, SR-8.18, SR-9.4). The daemon's own READY/WATCHDOG lines through systemd's
protocol are checked end to end in ``tests/daemon/test_srcsd.py``."""

from __future__ import annotations

import logging
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.daemon.notify import Notifier
from supervisord.daemon.service_manager import ServiceManager, status_text
from supervisord.safety.causes import CauseState
from supervisord.safety.decision import Decision
from supervisord.safety.transitions import State
from supervisord.timebase import NS_PER_MS
from supervisord.vocabulary import Cause, CauseKind

WATCHDOG_USEC = 200_000  # WatchdogSec=200ms: WATCHDOG=1 every 100 ms
INTERVAL_NS = 100 * NS_PER_MS


def _cause(kind: CauseKind, *, active: bool = True, **details: str) -> CauseState:
    return CauseState(Cause(kind), active, not active, 0, None, tuple(sorted(details.items())))


def _decision(state: State, *causes: CauseState, now: int = 0) -> Decision:
    return Decision(
        now=now,
        state=state,
        causes=causes,
        outputs={},
        heartbeat_estop=0,
        next_deadline=now + 1,
    )


class Systemd:
    """The service manager's end of NOTIFY_SOCKET: what the daemon sent, one datagram a line."""

    def __init__(self, path: Path) -> None:
        self.socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.socket.bind(str(path))
        self.socket.setblocking(False)

    def datagrams(self) -> list[str]:
        got = []
        while True:
            try:
                got.append(self.socket.recv(4096).decode())
            except BlockingIOError:
                return got


@pytest.fixture
def systemd(tmp_path: Path) -> Iterator[tuple[Systemd, ServiceManager]]:
    path = tmp_path / "notify"
    server = Systemd(path)
    env = {"NOTIFY_SOCKET": str(path), "WATCHDOG_USEC": str(WATCHDOG_USEC)}
    service = ServiceManager(Notifier(env))
    try:
        yield server, service
    finally:
        service.close()
        server.socket.close()


def test_status_text_is_the_state_then_every_active_or_latched_cause() -> None:
    startup = _cause(CauseKind.STARTUP, active=False)
    estop = _cause(CauseKind.VSC_ESTOP)
    assert status_text(_decision(State.RUN)) == "RUN"
    assert status_text(_decision(State.STOPPED, startup, estop)) == "STOPPED: startup, vsc_estop"


def test_ready_carries_the_status_and_the_watchdog_is_due_at_once(
    systemd: tuple[Systemd, ServiceManager],
) -> None:
    server, service = systemd
    assert service.next_watchdog is None  # not before READY
    service.ready(1_000, _decision(State.STOPPED, _cause(CauseKind.STARTUP)))
    assert server.datagrams() == ["READY=1\nSTATUS=STOPPED: startup\n"]
    assert service.next_watchdog == 1_000


def test_the_watchdog_is_sent_when_due_and_then_every_half_watchdogsec(
    systemd: tuple[Systemd, ServiceManager],
) -> None:
    server, service = systemd
    service.ready(0, _decision(State.STOPPED))
    server.datagrams()
    service.watchdog(0)
    assert server.datagrams() == ["WATCHDOG=1\n"]
    assert service.next_watchdog == INTERVAL_NS
    service.watchdog(INTERVAL_NS - 1)  # not due yet: nothing
    assert server.datagrams() == []
    late = INTERVAL_NS + 30 * NS_PER_MS  # a late turn: the next one counts from when it went
    service.watchdog(late)
    assert server.datagrams() == ["WATCHDOG=1\n"]
    assert service.next_watchdog == late + INTERVAL_NS


def test_without_a_watchdog_nothing_is_ever_due(tmp_path: Path) -> None:
    path = tmp_path / "notify"
    server = Systemd(path)
    service = ServiceManager(Notifier({"NOTIFY_SOCKET": str(path)}))
    try:
        service.ready(0, _decision(State.STOPPED))
        assert service.next_watchdog is None
        service.watchdog(10**12)
        assert server.datagrams() == ["READY=1\nSTATUS=STOPPED\n"]
    finally:
        service.close()
        server.socket.close()


def test_the_status_line_is_sent_only_when_its_text_changes(
    systemd: tuple[Systemd, ServiceManager],
) -> None:
    """SR-9.4: the loop asks only when the causes or the state changed (by identity, read
    from ``causes`` and ``state``); the line goes out only when its text did."""
    server, service = systemd
    hold = _decision(State.HOLD, _cause(CauseKind.VSC_ESTOP))
    service.decided(hold)
    assert (service.causes, service.state) == (hold.causes, State.HOLD)
    same_text = _decision(State.HOLD, _cause(CauseKind.VSC_ESTOP))  # new tuple, same line
    assert same_text.causes is not hold.causes
    service.decided(same_text)
    service.decided(_decision(State.RUN))
    assert server.datagrams() == ["STATUS=HOLD: vsc_estop\n", "STATUS=RUN\n"]
    assert service.status == "RUN"


def test_stopping_says_the_outputs_go_off(systemd: tuple[Systemd, ServiceManager]) -> None:
    server, service = systemd
    service.stopping()
    assert server.datagrams() == ["STOPPING=1\nSTATUS=stopping: outputs off\n"]


def test_a_watchdog_answered_off_is_said_once_with_its_fix(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.18: said when the VSC answers key 85 with another value than 1, naming the
    command that reaches this daemon; not while it has not answered; again after it was on."""
    service = ServiceManager(Notifier({}), srcsctl="srcsctl -R robot-a")
    unanswered = _cause(CauseKind.VSC_WATCHDOG_OFF, key85="no answer")
    off = _cause(CauseKind.VSC_WATCHDOG_OFF, key85="0")
    with caplog.at_level(logging.WARNING, logger="srcsd"):
        service.decided(_decision(State.STOPPED, unanswered))
        assert not caplog.records
        service.decided(_decision(State.STOPPED, off))
        service.decided(_decision(State.STOPPED, off, _cause(CauseKind.VSC_ESTOP)))
        assert len(caplog.records) == 1
        assert "srcsctl -R robot-a" in caplog.records[0].getMessage()
        service.decided(_decision(State.STOPPED))  # answered 1: commissioned
        service.decided(_decision(State.STOPPED, off))
        assert len(caplog.records) == 2


def test_a_watchdog_answered_off_in_the_first_decision_is_said(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.18: nothing was said before the first decision, so a first decision that already
    has the VSC's answer (key 85 off) says it."""
    service = ServiceManager(Notifier({}), srcsctl="srcsctl -R robot-a")
    off = _cause(CauseKind.VSC_WATCHDOG_OFF, key85="0")
    with caplog.at_level(logging.WARNING, logger="srcsd"):
        service.decided(_decision(State.STOPPED, off))
    assert len(caplog.records) == 1
    assert "srcsctl -R robot-a" in caplog.records[0].getMessage()
