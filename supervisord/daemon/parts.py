"""The daemon loop's parts, built from what srcsd's assembly or a test hands over.

Each part has one job and its own module (``docs/safety.md`` "The loop's parts"): the link
port (SR-2, SR-5.1), the output bank (SR-6, SR-9.4, SR-9.5) with each stop's times to off
(SR-12.1), the record path (SR-7.4, SR-7.7, SR-7.10, SR-13.12), the waiter (SR-9.4, SR-10.1),
the service manager's face (SR-0.2, SR-6.5), the refusal log (SR-8.5), the stop request
(SR-6.6, SR-7.14), the schedule of the periodic tests (SR-12.2), the counters and the
histograms. :class:`Parts` builds them, once, and holds them; it decides nothing, and asks
the parts only for the daemon's own status (:meth:`Parts.snapshot`, docs/api.md "status").
The loop (:class:`~supervisord.daemon.loop.Supervisor`) is its subclass, so a turn reaches
each part in one attribute lookup, as before the parts were built here (SR-9.4: the stop path
pays nothing for the split); what the loop holds of its own is only the core and the last
decision it applied.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Mapping, Sequence

from supervisord.api.status import LoopStatus
from supervisord.clock import MONOTONIC, Clock
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.listener import Listener
from supervisord.daemon.loop_status import Counters, loop_status
from supervisord.daemon.maintenance import Schedule
from supervisord.daemon.notify import Notifier
from supervisord.daemon.output_bank import OutputBank
from supervisord.daemon.record_path import RecordPath
from supervisord.daemon.refusal_log import RefusalLog
from supervisord.daemon.service_manager import ServiceManager
from supervisord.daemon.stop_request import StopRequest
from supervisord.daemon.stoptimes import StopTimes
from supervisord.daemon.timings import Timings
from supervisord.daemon.waiter import Waiter
from supervisord.links.base import Backoff, Link
from supervisord.outputs.base import Output
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import SafetyConfig

__all__ = ["Parts"]


def _utc_now() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc)


class Parts:
    """The loop's parts, built from the configuration's safety section, the link, the
    outputs and the record's writer (``None``: no record file, a test's loop)."""

    def __init__(
        self,
        safety: SafetyConfig,
        link: Link,
        outputs: list[Output],
        writer: RecordWriter | None,
        *,
        journal: Callable[[Mapping[str, object]], object] | None = None,
        flight_journal: Callable[[Sequence[tuple[str, str]]], object] | None = None,
        listener: Listener | None = None,
        notifier: Notifier | None = None,
        clock: Clock = MONOTONIC,
        wall_clock: Callable[[], dt.datetime] = _utc_now,
        backoff: Backoff | None = None,
        release: list[Callable[[], object]] | None = None,
        flight: FlightSettings | None = FlightSettings(),  # noqa: B008 -- frozen
    ) -> None:
        self.safety = safety
        self.clock = clock  # the loop's one clock (SR-2.11)
        # The client API listener; a loop built by a test may have none (an empty one).
        self.listener = listener or Listener()
        # READY, STATUS, WATCHDOG and STOPPING, and when the watchdog is due (SR-0.2, SR-6.5).
        self.service = ServiceManager(notifier or Notifier({}))
        # The record path: the sink and its lanes, the records it holds, the flight ring, and
        # each record's and stop window's journal copy (SR-7.4, SR-7.7, SR-7.10, SR-13.12).
        self.records = RecordPath(
            safety,
            writer,
            journal=journal,
            flight_journal=flight_journal,
            flight=flight,
            wall_clock=wall_clock,
        )
        self.counters = Counters()
        self.timings = Timings()
        # The link: open with its backoff, receive, send, close and release, its counters
        # (SR-2, SR-5.1).
        self.port = LinkPort(link, clock, self.timings, backoff, release or ())
        self.schedule = Schedule({})  # the periodic tests' last passes (SR-12.2)
        # The outputs: acquire with a backoff, apply levels with the reflex's writes and the
        # steady path's test, read back, all off (SR-6, SR-9.4, SR-9.5); and each stop's
        # outputs' times to off (SR-12.1), a category-1 output judged after its delay.
        delays = {o.name: o.off_delay_ms for o in safety.outputs}
        self.bank = OutputBank(outputs, clock, StopTimes(delays=delays))
        # Whether the start locked the memory (SR-9.6): set by srcsd, ``None`` when no start
        # said (a loop built by a test).
        self.memory_locked: bool | None = None
        # Whether the loop was asked to end, and the first signal that asked (SR-6.6, SR-7.14).
        self.stop = StopRequest()
        # The loop's wait: epoll and what it watches, the wake pair, the clients' order (SR-9.4,
        # SR-10.1).
        self.waiter = Waiter()
        # The refusals under the record budget: counted, logged once a second (SR-8.5).
        self.refusals = RefusalLog()

    @property
    def link(self) -> Link:
        """The link to the VSC (its port's), as srcsd names it in its start-up line."""
        return self.port.link

    @property
    def outputs(self) -> dict[str, Output]:
        """The outputs by name (the bank's), as srcsd counts them in its start-up line."""
        return self.bank.outputs

    @property
    def srcsctl(self) -> str:
        """How a fix names the command that reaches this daemon (SR-8.18), set by srcsd."""
        return self.service.srcsctl

    @srcsctl.setter
    def srcsctl(self, srcsctl: str) -> None:
        self.service.srcsctl = srcsctl

    def snapshot(self, now: int) -> LoopStatus:
        """What ``status`` says about the daemon itself at ``now`` (the loop's clock), from the
        parts' own status (:func:`~supervisord.daemon.loop_status.loop_status`)."""
        return loop_status(
            now,
            started_ns=self.counters.started_ns,
            safety=self.safety,
            port=self.port,
            bank=self.bank,
            records=self.records,
            refusals=self.refusals,
            counters=self.counters,
            timings=self.timings,
            schedule=self.schedule,
            memory_locked=self.memory_locked,
        )
