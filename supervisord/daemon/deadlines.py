"""When the loop must wake next, and whether the stop path waits: the turn's two questions
about time, answered from the parts' own deadlines.

The loop asks :func:`next_deadline` before each wait (the earliest of the core's deadline, the
outputs' periodic duties or acquisition, a link reopen or poll, the systemd watchdog, the
listener's own work), and :func:`stop_path_waits` between two client descriptors (whether the
link has bytes to read or the core's deadline has come: those are served first, SR-10.1,
``docs/safety.md`` "The stop path first"). Deadlines are on the loop's monotonic clock (SR-2).
Both hold nothing and call nothing back.
"""

from __future__ import annotations

import select

from supervisord.clock import Clock
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.listener import Listener
from supervisord.daemon.output_bank import OutputBank
from supervisord.daemon.service_manager import ServiceManager
from supervisord.links.base import Link
from supervisord.timebase import NS_PER_MS

__all__ = ["POLL_NS", "next_deadline", "stop_path_waits"]

POLL_NS = 2 * NS_PER_MS  # a link without a descriptor (python-can "virtual") is polled


def next_deadline(  # noqa: PLR0917 -- once a turn: positional, the cheaper call (SR-9.4)
    now: int,
    core_deadline: int,
    link_fd: int | None,
    port: LinkPort,
    bank: OutputBank,
    service: ServiceManager,
    listener: Listener,
) -> int:
    """The earliest deadline of the loop's at ``now`` (the clock read before the wait), from
    the core's ``core_deadline`` and the link's descriptor as read then (``None``: closed, or
    polled)."""
    deadline = core_deadline
    if bank.ticking or bank.acquiring:  # the usual bank has neither: no call (SR-9.4)
        deadline = bank.next_deadline(deadline)
    if link_fd is None:
        if not port.link.is_open:
            deadline = min(deadline, port.next_attempt)
        else:
            deadline = min(deadline, now + POLL_NS)
    watchdog = service.next_watchdog
    if watchdog is not None and watchdog < deadline:
        deadline = watchdog
    listener_deadline = listener.next_deadline()
    if listener_deadline is not None and listener_deadline < deadline:
        deadline = listener_deadline
    return deadline


def stop_path_waits(clock: Clock, core_deadline: int | None, link: Link) -> bool:
    """Whether the core's deadline has come (``clock`` read only when there is one) or the
    link has bytes to read."""
    if core_deadline is not None and clock() >= core_deadline:
        return True
    fd = link.fileno() if link.is_open else None
    if fd is None:
        return False
    readable, _, _ = select.select([fd], [], [], 0)
    return bool(readable)
