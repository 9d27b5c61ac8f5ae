"""The one loop of ``srcsd``: it owns every piece of state and every safety duty.

It waits on the link's descriptor, the client socket, a signal pipe and the earliest deadline
(the safety core's, the outputs' periodic duties, a link reopen, the systemd watchdog), feeds
what happened to the safety core, and applies each decision at once: outputs first, then the
frames to the VSC (SR-6). Every turn serves the stop path first: the link to the
VSC, then the core's timers (user heartbeat, link-loss and client deadlines), and only then a
bounded number of client descriptors (:data:`MAX_CLIENTS_PER_TURN`, fewer when the link has
more to read or a deadline has come), so no client can push the VSC's next frame or the user
heartbeat back (SR-10.1, ``docs/safety.md`` "The stop path first").

Records, journal entries and log lines leave the loop through the :class:`~supervisord.daemon.
sink.Sink` that it never waits for (a lane each: its record thread writes and fsyncs, SR-7.7);
a record is pushed to subscribers once the sink says it is on disk. Every input the core is
given also goes into the flight recorder's ring, and each stop's window leaves through the
sink's flight lane (:mod:`~supervisord.daemon.flight`, SR-7.10 to SR-7.12). The user
heartbeat, the outputs and the link are served only by this loop, so if it hangs, the
heartbeat stops and the VSC's key-85 watchdog opens its relays (SR-5).

The loop keeps the turn's order and the apply order; parts with narrow faces do the rest, each
told what it needs as arguments and answering with values, none calling back into the loop
(``docs/safety.md`` "The loop's parts"): the wait (:mod:`~supervisord.daemon.waiter`: epoll,
its watches, the wake pair, the clients' order), the link port
(:mod:`~supervisord.daemon.link_port`: open with a backoff, receive, send, its counters) and
the service manager's face (:mod:`~supervisord.daemon.service_manager`: READY, STATUS,
WATCHDOG, STOPPING).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import logging
import os
import select
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from supervisord import __version__
from supervisord.api.status import LoopStatus
from supervisord.api.views import histogram_status
from supervisord.clock import MONOTONIC, Clock
from supervisord.daemon import heap, signals
from supervisord.daemon.flight import FlightRecorder, FlightSettings
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.maintenance import Schedule
from supervisord.daemon.notify import Notifier
from supervisord.daemon.offcheck import OffCheck, check_off
from supervisord.daemon.reflex import EarlyOff
from supervisord.daemon.service_manager import ServiceManager
from supervisord.daemon.sink import IDLE_STATUS, Sink, Written
from supervisord.daemon.stoptimes import StopTimes
from supervisord.daemon.timings import Timings
from supervisord.daemon.waiter import Waiter
from supervisord.links.base import Backoff, Link
from supervisord.outputs.base import Output, OutputError, ReadBack
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message, VscHeartbeat
from supervisord.record.flight import FlightWriter
from supervisord.record.format import stop_record
from supervisord.record.jsonl import RecordWriter
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision, Record, RefusalReason
from supervisord.safety.events import (
    Event,
    InternalFault,
    LinkBroken,
    OutputReadback,
    Shutdown,
    Tick,
    VscReceived,
)
from supervisord.safety.transitions import State
from supervisord.timebase import NS_PER_MS, NS_PER_S, seconds_since

log = logging.getLogger("srcsd")

POLL_NS = 2 * NS_PER_MS  # a link without a descriptor (python-can "virtual") is polled
OVERRUN_NS = 250 * NS_PER_MS  # woke this late after the core's deadline: the loop is failing
MAX_SETTLE_STEPS = 8  # output read-backs fed back to the core per input, at most
ACQUIRE_FIRST_MS, ACQUIRE_MAX_MS = 500, 10_000  # retrying an output that could not be acquired
MAX_CLIENTS_PER_TURN = 4  # client descriptors served per turn, at most (docs/safety.md)
LIMIT_LOG_NS = NS_PER_S  # rate-limited refusals are logged as a count, once a second


@dataclass
class Counters:
    """What the loop has seen, for ``srcsctl status`` (the link's counts are its port's)."""

    record_errors: int = 0
    records_dropped: int = 0
    rate_limited: int = 0
    internal_faults: int = 0


@dataclass(frozen=True, slots=True)
class Snapshot:
    """What the loop hands the listener with every call: ``status(now)``, the loop's own
    status at a time (:meth:`Supervisor.snapshot`, for a ``status`` reply), and
    ``stop_times``, the last stops' outputs' times to off, measured by the loop (for a
    ``stoptest``, SR-12.1), and ``check_off()``, every output written off again and read
    back now, for a fleet stop's acknowledgement (SR-8.20, ``offcheck.py``; ``None``: a loop
    that has no outputs to check)."""

    status: Callable[[int], LoopStatus]
    stop_times: StopTimes
    check_off: Callable[[], OffCheck] | None = None


class Listener:
    """Something else the loop serves (the client API): descriptors to watch and callbacks.

    ``decided`` and ``received`` are told every decision and every valid VSC message, so
    clients see state, records and traffic as they happen.
    """

    def descriptors(self, now: int) -> Iterable[tuple[int, bool]]:
        """(fd, wants_write) pairs to watch now (``now``: the loop's clock, as everywhere)."""
        return ()

    def urgent(self) -> frozenset[int]:
        """Descriptors (of :meth:`descriptors`) served before the other client descriptors
        and outside :data:`MAX_CLIENTS_PER_TURN`: the operator socket (SR-8.14)."""
        return frozenset()

    def handle(
        self,
        fd: int,
        readable: bool,
        writable: bool,
        now: int,
        feed: Callable[[Event], Decision],
        *,
        snapshot: Snapshot,
    ) -> None:
        """Serve ``fd``; every safety input goes through ``feed``, which applies it at once
        and returns the core's decision (to answer with its refusals); ``snapshot.status(now)`` is
        what the loop says about itself, for a ``status`` reply; ``snapshot.stop_times``
        its stops' measured times to off, for a ``stoptest``."""

    def settle(self, now: int, feed: Callable[[Event], Decision], *, snapshot: Snapshot) -> None:
        """Serve, through ``feed``, the safety inputs that arose outside ``handle`` (e.g. a
        client dropped while a push was written to it). Called once at the end of a turn.
        ``feed`` and ``snapshot`` as for :meth:`handle`."""

    def due(
        self, now: int, feed: Callable[[Event], Decision], *, snapshot: Snapshot
    ) -> list[Message]:
        """Work of the listener's own that is due (commissioning, requests that waited for
        the caller's name): frames to send to the VSC. ``feed`` and ``snapshot`` as for
        :meth:`handle`."""
        return []

    def next_deadline(self) -> int | None:
        """When ``due`` must be called next, if the listener has work of its own."""
        return None

    def decided(self, decision: Decision) -> None:
        """A decision was applied (outputs set, frames sent)."""

    def recorded(self, record: StopRecord) -> None:
        """A stop record is finished: on disk, or counted as not written. Called in record
        order, after the decision that made it."""

    def received(self, message: Message | HidInput, now: int) -> None:
        """A valid message arrived from the VSC, read at ``now``."""

    def close(self) -> None:
        """Release everything."""


class Supervisor:
    """The daemon's state and loop. ``run`` returns the process exit status."""

    steady_path = True
    """Apply a decision that changes nothing the full path would act on without it (the
    decisions of the core's cheap path, 90 a second in RUN): :meth:`_apply`. The full path is
    the reference: ``tests/daemon/test_steady_path.py`` switches this off on one of two loops
    fed the same inputs and checks that both do the same (SR-9.4)."""

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
        wall_clock: Callable[[], dt.datetime] = lambda: dt.datetime.now(dt.timezone.utc),
        backoff: Backoff | None = None,
        release: list[Callable[[], object]] | None = None,
        flight: FlightSettings | None = FlightSettings(),  # noqa: B008 -- frozen
    ) -> None:
        self.safety = safety
        self.link = link
        self.outputs = {output.name: output for output in outputs}
        # The outputs with a periodic duty (their kind has a ``next_deadline`` of its own: a CAN
        # enable frame, a GPIO pulse): the only ones the loop asks for a deadline every turn
        # (SR-9.4); the others' is always ``None``.
        self._ticking = [o for o in outputs if type(o).next_deadline is not Output.next_deadline]
        self.writer = writer
        # Each record's journal copy, and each stop window's (SR-13.12).
        self.journal, self.flight_journal = journal, flight_journal
        self.listener = listener or Listener()
        # READY, STATUS, WATCHDOG and STOPPING, and when the watchdog is due (SR-0.2, SR-6.5).
        self.service = ServiceManager(notifier or Notifier({}))
        self.clock = clock
        self.wall_clock = wall_clock
        self.counters = Counters()
        self.timings = Timings()
        # The link: open with its backoff, receive, send, its counters (SR-2, SR-5.1).
        self.port = LinkPort(link, clock, self.timings, backoff)
        # Each stop's outputs' times to off (SR-12.1), a category-1 output judged after its delay.
        self.stop_times = StopTimes(delays={o.name: o.off_delay_ms for o in safety.outputs})
        self.schedule = Schedule({})  # the periodic tests' last passes (SR-12.2)
        self._early = EarlyOff(self.outputs, self.clock)  # the reflex's writes (SR-9.5)
        # Handed to the listener.
        self._snapshot = Snapshot(self.snapshot, self.stop_times, self._check_off)
        self._release = release or []
        # Sequence numbers continue the record across restarts (the core counts from 1).
        self.sequence_offset = 0
        self.core: SafetyCore | None = None
        self.decision: Decision | None = None
        self._stop_requested = False
        self._stop_signal: int | None = None  # the signal that asked for the stop (SR-6.6)
        self._acquiring: dict[str, Backoff] = {}  # outputs not acquired yet, and when to retry
        # The outputs' levels the last decision set, every one of them (each output named is
        # open and was left at its level): the mapping object itself, for the steady path.
        # ``None`` once anything else drives or opens an output.
        self._applied_outputs: Mapping[str, bool] | None = None
        # The loop's wait: epoll and what it watches, the wake pair, the clients' order (SR-9.4,
        # SR-10.1).
        self.waiter = Waiter()
        self.sink: Sink | None = None
        self._limited_unlogged = self._next_limit_log = 0  # refusals not logged yet, and when
        self._started_ns: int | None = None  # for ``status``: uptime
        self._version_due = True  # the first record of this start names the version
        # The typed records the sink has as JSON, by ``seq``, until it says what became of
        # each: the API pushes the typed record itself, never one read back from its JSON.
        self._in_sink: dict[int, StopRecord] = {}
        # The flight recorder (SR-7.10): beside a record file only, as its windows are.
        self.flight: FlightRecorder | None = None
        self._flight_writer: FlightWriter | None = None
        if writer is not None and flight is not None:
            self.flight = FlightRecorder(safety, flight)
            self._flight_writer = FlightWriter(writer.path, writer.max_bytes, flight.max_bytes)

    @property
    def srcsctl(self) -> str:
        """How a fix names the command that reaches this daemon (SR-8.18), set by srcsd."""
        return self.service.srcsctl

    @srcsctl.setter
    def srcsctl(self, srcsctl: str) -> None:
        self.service.srcsctl = srcsctl

    def snapshot(self, now: int) -> LoopStatus:
        """What ``status`` says about the daemon itself at ``now`` (the loop's clock): its
        version and uptime, the link and the loop's counters (docs/api.md "status"). The
        listener is handed this method, and builds the ``status`` reply with it."""
        counters = self.counters
        return LoopStatus(
            pid=os.getpid(),
            version=__version__,
            uptime_s=seconds_since(now, self._started_ns),
            link=self.port.status(now),
            outputs_not_acquired=tuple(sorted(self._acquiring)),
            # SR-1.4: each category-1 output's delay after the motion outputs (docs/outputs.md
            # "Stop categories"); an output not named is category 0.
            outputs_off_delay_ms={
                o.name: o.off_delay_ms for o in self.safety.outputs if o.off_delay_ms
            },
            messages=self.port.messages,
            rejections=dict(sorted(self.port.rejections.items())),
            record_errors=counters.record_errors,
            records_dropped=counters.records_dropped,
            # records_pending, journal_errors and _dropped, log_lines_dropped, record_reopens,
            # flight_windows, flight_errors (a snapshot's too) and flight_dropped
            sink=self._sink_status(),
            rate_limited=counters.rate_limited,
            internal_faults=counters.internal_faults,
            histograms={name: histogram_status(h) for name, h in self.timings.histograms().items()},
            # the periodic tests: each one's interval, last pass's age, overdue (SR-12.2)
            maintenance=self.schedule.status(now),
        )

    def _sink_status(self) -> dict[str, int]:
        status = dict(self.sink.status() if self.sink is not None else IDLE_STATUS)
        if self.flight is not None:
            status["flight_errors"] += self.flight.snapshot_errors
        return status

    # ----------------------------------------------------------------- start and stop

    def start(self) -> Decision:
        """Outputs off before anything else, then the core, then the link (SR-6).

        Returns the first decision. An output that cannot be acquired (busy, missing, not
        permitted) is ``output_fault:NAME``: the daemon stays up, STOPPED, says so, and tries
        again with a backoff, because a supervisor that exits holds nothing and reports nothing.
        Once acquired (off), the fault's condition clears; its stop waits for a re-arm (SR-4).
        """
        now = self.clock()
        self._started_ns = self.port.since_ns = now
        self.schedule.start(self.wall_clock(), now)  # the passes read from the record
        self.sink = Sink(
            self.writer,
            self.journal,
            flight=self._flight_writer,
            flight_journal=self.flight_journal,
        )
        self.sink.start()
        events: list[Event] = []
        for output in self.outputs.values():
            try:
                events.append(self._readback_event(output.open(now), now))
            except OutputError as error:
                log.error("output %s cannot be acquired: %s (retrying)", output.name, error)
                events.append(OutputReadback(now, output.name, False, None))
                self._acquiring[output.name] = backoff = Backoff(ACQUIRE_FIRST_MS, ACQUIRE_MAX_MS)
                backoff.failed(now)
        self.core = SafetyCore(self.safety, now)
        if self.flight is not None:
            self.flight.start(now, self.sequence_offset)  # a window can start from here
        self._apply(self.core.decision)  # the startup decision, with the first record
        for event in events:
            self._apply(self._feed(event))
        self._apply(self._feed(self.port.open(now)))
        self.waiter.start(self.sink.fileno())
        assert self.decision is not None
        self.service.ready(now, self.decision)  # the startup decision applied: outputs off
        return self.decision

    def request_stop(self, signum: int | None = None) -> None:
        """Ask the loop to end (from a signal handler: only sets a flag and wakes the loop).
        The first signal asked for decides the exit status (SR-6.6)."""
        if self._stop_signal is None:
            self._stop_signal = signum
        self._stop_requested = True
        self.waiter.wake()

    def shutdown(self) -> None:
        """All outputs off, then release the link; drain the record (every queued record
        written and fsynced, and pushed to subscribers, within the sink's deadline), then the
        socket (SIGTERM path)."""
        self.service.stopping()
        self._applied_outputs = None  # every output driven off and closed here
        now = self.clock()
        for output in self.outputs.values():
            with contextlib.suppress(Exception):
                output.set(False, now)
            with contextlib.suppress(Exception):
                output.close()
        self.link.close()
        for release in self._release:
            with contextlib.suppress(Exception):
                release()
        # Then the stop's record, after the outputs (SR-7.14): the core makes it, so its
        # ``seq`` continues the file's and a replay makes it again; the outputs and the link
        # are closed by now, so the decision switches and sends nothing.
        with contextlib.suppress(Exception):
            self._record_shutdown(self.clock())
        if self.sink is not None:
            # The records first, with a deadline well inside the unit's stop timeout, then
            # pushed; then journal copies and log lines, best effort (SR-7.7).
            self.sink.drain_records()
            with contextlib.suppress(Exception):
                self._take_written()
            self.sink.close()  # closes the writer, unless a write is stuck in the disk
        elif self.writer is not None:
            self.writer.close()
        self.listener.close()
        self.waiter.close()
        self.service.close()

    def _record_shutdown(self, now: int) -> None:
        """The ``shutdown:REASON`` stop (SR-7.14): REASON is the signal that asked for the
        exit (``SIGTERM``), ``requested`` for :meth:`request_stop` without one, or ``error``
        when an exception ends :meth:`run` (its start failed). Every exit
        is recorded, in STOPPED and HOLD too (a cause raised, or a stop)."""
        if self.core is None:
            return  # the core never started: there is no sequence to continue
        if self._stop_signal is not None:
            reason = signals.name(self._stop_signal)
        else:  # asked for without a signal (an embedding program), or an exception
            reason = "requested" if self._stop_requested else "error"
        self._apply(self._feed(Shutdown(now, reason)))

    def run(self) -> int:
        """Start, loop until a stopping signal, shut down. Every signal that would end the
        process ends it this way, outputs off and the record drained, except those with a
        purpose of their own (SR-6.6, :mod:`~supervisord.daemon.signals`). Exit status 0
        after SIGTERM or SIGINT, 128 + N after another signal N."""
        previous = signals.install(self.request_stop)
        try:
            self.start()
            if self.sink is not None:
                # Log lines leave the loop through the sink too: a slow stderr or journald
                # must not hold the loop (SR-7.5).
                self.sink.capture_logging(logging.getLogger())
            heap.settle()  # no full scan of start-up's objects in the loop (SR-9.1, SR-9.4)
            while not self._stop_requested:
                self.step()
            if self._stop_signal is not None:
                # Before the shutdown, so that the sink drains it with the records.
                level = logging.INFO if self._stop_signal in signals.CLEAN_EXIT else logging.WARNING
                log.log(level, "%s: stopping, every output off", signals.name(self._stop_signal))
        finally:
            try:
                # A second signal during the shutdown changes nothing: the handlers stay
                # until the outputs are off and the record is drained.
                self.shutdown()
            finally:
                signals.restore(previous)
        return 0 if self._stop_signal is None else signals.exit_status(self._stop_signal)

    # ----------------------------------------------------------------- the loop

    def step(self) -> None:
        """Wait for the next input or deadline, then serve, in this order: the link to the
        VSC, the core's and the outputs' timers, the record sink's news, and at most
        :data:`MAX_CLIENTS_PER_TURN` client descriptors (SR-10.1; docs/safety.md "The stop
        path first"). Each input is stamped with the clock read when it was read."""
        before = self.clock()
        flight = self.flight
        if flight is not None and flight.due(before):
            self._rebase_flight(before)  # before the wait: never between an input and its outputs
        link = self.link
        link_fd = link.fileno() if link.is_open else None  # once, for the deadline and the watch
        timeout = max(0.0, (self._next_deadline(before, link_fd) - before) / 1e9)
        waiter = self.waiter
        waiter.watch(link_fd, self.listener.descriptors(before))
        ready = waiter.wait(timeout)
        now = self.clock()
        try:
            core_deadline = self.decision.next_deadline if self.decision else now
            if now - core_deadline > OVERRUN_NS:
                late = (now - core_deadline) // NS_PER_MS
                self._apply(self._feed(InternalFault(now, f"loop woke {late} ms late")))
            if not ready:  # a deadline's turn: nothing to sort (SR-9.4)
                received, sink_ready, clients = False, False, None
            elif len(ready) == 1 and ready[0][0] == waiter.link_fd:  # a frame's turn: the same
                received, sink_ready, clients = True, False, None
            else:  # the sink's is taken after the timers
                received, sink_ready, clients = waiter.sort(ready)
            if received:
                self._receive()
            elif waiter.link_fd is None and link.is_open and link.fileno() is None:
                self._receive()  # a link without a descriptor is polled
                received = True
            # The timers at the time the wait returned, or after the read when there was one
            # (its work took time): one clock read fewer on a timer's turn (SR-9.4).
            self._due(self.clock() if received else now)
            if sink_ready:
                # Only when the sink said so (its socket is readable once a record is
                # finished): not a system call per turn (SR-9.4).
                self._take_written()
            if clients:
                self._serve_clients(clients)
            self.listener.settle(self.clock(), self._feed_and_apply, snapshot=self._snapshot)
        except Exception as error:
            self._internal_fault(self.clock(), error)

    def _serve_clients(self, ready: list[tuple[int, int]]) -> None:
        """Serve up to MAX_CLIENTS_PER_TURN ready client descriptors, in the waiter's order
        (starting after the one served last, so every client gets its turn), and stop early
        when the link has bytes waiting or a core deadline has come: those go first
        (docs/safety.md). The listener's urgent descriptors (the operator socket, SR-8.14) come
        before them all, uncounted."""
        waiter, listener = self.waiter, self.listener
        first, ordered = waiter.order(ready, listener.urgent())
        for fd, mask in first:
            readable, writable = waiter.readiness(fd, mask)
            listener.handle(
                fd, readable, writable, self.clock(), self._feed_and_apply, snapshot=self._snapshot
            )
        for served, (fd, mask) in enumerate(ordered):
            if served >= MAX_CLIENTS_PER_TURN or (served and self._stop_path_waits()):
                return  # the rest stay ready: the next turn serves them
            waiter.cursor = fd
            readable, writable = waiter.readiness(fd, mask)
            # The clock read right before the read: the time this client input was read (SR-2).
            listener.handle(
                fd, readable, writable, self.clock(), self._feed_and_apply, snapshot=self._snapshot
            )

    def _stop_path_waits(self) -> bool:
        """Whether the link has bytes to read or the core's deadline has come."""
        if self.decision is not None and self.clock() >= self.decision.next_deadline:
            return True
        fd = self.link.fileno() if self.link.is_open else None
        if fd is None:
            return False
        readable, _, _ = select.select([fd], [], [], 0)
        return bool(readable)

    def _next_deadline(self, now: int, link_fd: int | None) -> int:
        """The earliest deadline of the loop's, at ``now`` (the clock read before the wait),
        with the link's descriptor as read then (``None``: closed, or polled)."""
        deadline = self.decision.next_deadline if self.decision else now
        for output in self._ticking:
            if output.is_open and (due := output.next_deadline()) is not None and due < deadline:
                deadline = due
        if link_fd is None:
            if not self.link.is_open:
                deadline = min(deadline, self.port.next_attempt)
            else:
                deadline = min(deadline, now + POLL_NS)
        watchdog = self.service.next_watchdog
        if watchdog is not None and watchdog < deadline:
            deadline = watchdog
        for backoff in self._acquiring.values():
            deadline = min(deadline, backoff.next_attempt)
        listener_deadline = self.listener.next_deadline()
        if listener_deadline is not None and listener_deadline < deadline:
            deadline = listener_deadline
        return deadline

    def _due(self, now: int) -> None:
        if self.decision is not None and now >= self.decision.next_deadline:
            assert self.core is not None
            # A stop at a deadline (a link or client timeout) started at the deadline, not
            # when the loop woke: its stop-to-off counts the wake-up too (SR-9.2).
            self._apply(self._feed(Tick(now)), since=self.decision.next_deadline)
        for output in self._ticking:
            deadline = output.next_deadline() if output.is_open else None
            if deadline is not None and now >= deadline:
                readback = output.tick(now)
                if readback is not None and not readback.ok:
                    self._apply(self._feed(self._readback_event(readback, now)))
        if self._acquiring:
            for name, backoff in list(self._acquiring.items()):
                if now >= backoff.next_attempt:
                    self._acquire(name, backoff, now)
        listener_deadline = self.listener.next_deadline()
        if listener_deadline is not None and now >= listener_deadline:
            self._send(
                tuple(self.listener.due(now, self._feed_and_apply, snapshot=self._snapshot)), now
            )
        if self.waiter.link_fd is None and not self.link.is_open and now >= self.port.next_attempt:
            # (A link watched this turn was open: one that broke in it has just set its backoff.)
            self._apply(self._feed(self.port.open(now)))
        service = self.service
        if service.next_watchdog is not None and now >= service.next_watchdog:
            service.watchdog(now)

    def _acquire(self, name: str, backoff: Backoff, now: int) -> None:
        output = self.outputs[name]
        try:
            readback = output.open(now)
        except OutputError as error:
            backoff.failed(now)
            log.debug("output %s still cannot be acquired: %s", name, error)
            return
        del self._acquiring[name]
        self._applied_outputs = None  # an output opened (off): the next decision sets all
        log.info("output %s acquired (off)", name)
        self._apply(self._feed(self._readback_event(readback, now)))

    # ----------------------------------------------------------------- the link

    def _receive(self) -> None:
        """What the link brought, each message fed and applied in its order."""
        got = self.port.receive()
        if isinstance(got, LinkBroken):
            self._apply(self._feed(got))
            return
        now, received = got
        heartbeat = False
        received_by, flight, core = self.listener.received, self.flight, self.core
        assert core is not None
        for item in received:
            kind = type(item)
            if kind is VscHeartbeat:  # SR-9.5: a stop's outputs off before the full step
                self._early.heard(item, now, core)  # type: ignore[arg-type]
            received_by(item, now)
            if kind is not HidInput:
                # ``_feed`` written out: the ring, then the core (SR-7.10; one call fewer per
                # input, SR-9.4).
                event = VscReceived(now, item)  # type: ignore[arg-type]
                if flight is not None:
                    flight.inputs.append(event)
                    flight.count += 1
                self._apply(core.handle(event))
                if kind is VscHeartbeat:
                    heartbeat = True
        if heartbeat:
            # Observed after the decisions are applied: a heartbeat with an e-stop bit waits
            # for nothing (SR-9).
            self.port.heard(now)

    def _send(self, frames: tuple[Message, ...], now: int) -> None:
        broken = self.port.send(frames, now)
        if broken is not None:
            self._apply(self._feed(broken))

    # ----------------------------------------------------------------- decisions

    def _feed(self, event: Event) -> Decision:
        """Every input of the core goes through here, and into the flight recorder's ring (a
        reference appended and counted: SR-7.10)."""
        assert self.core is not None
        flight = self.flight
        if flight is not None:
            flight.inputs.append(event)
            flight.count += 1
        return self.core.handle(event)

    def _rebase_flight(self, now: int) -> None:
        """A snapshot of the core for the flight recorder's next windows (SR-7.11)."""
        assert self.flight is not None
        if self.core is None:
            return
        error = self.flight.rebase(self.core, now)
        if error is not None:
            name = type(error).__name__
            log.error("flight recorder: no snapshot of the core: %s: %s", name, error)

    def _check_off(self) -> OffCheck:
        """SR-8.20: every output off written off again and read back, for a fleet stop's
        acknowledgement; a read-back that disagrees goes to the core as any (SR-6)."""
        checked = check_off(self.outputs, self.clock, self.sequence_offset)
        for readback in checked.faults:
            self._apply(self._feed(self._readback_event(readback, checked.checked_ns)))
        return checked

    def _feed_and_apply(self, event: Event) -> Decision:
        decision = self._feed(event)
        self._apply(decision)
        return decision

    @staticmethod
    def _readback_event(readback: ReadBack, now: int) -> OutputReadback:
        observed = readback.observed if readback.fault is None else None
        if readback.fault is None and observed is None:
            observed = readback.written  # CAN: a frame that went out is the read-back
        return OutputReadback(now, readback.name, readback.requested, observed)

    def _apply(self, decision: Decision, since: int | None = None) -> None:
        """Outputs first, then frames, then records and status (SR-6).

        Setting outputs yields read-backs, which go back to the core; every decision that
        comes of them is applied in turn, so none of their records is lost (a read-back fault
        is a stop of its own, SR-7). ``since`` is when the input (or deadline) that led to
        ``decision`` was read (its ``now`` if not given), for the stop-to-off histogram."""
        previous = self.decision
        if (
            decision.outputs is self._applied_outputs
            and previous is not None
            and decision.state is previous.state
            and not decision.records
            and not decision.refusals
            and not self._early.written  # SR-9.5: the full path hands on the reflex's writes
            and self.steady_path
        ):
            # The steady path (SR-9.4): the same levels as the last decision set, every output
            # already at them (nothing else has driven one since), the same state (the stop
            # times were told already) and nothing to record or refuse: what the full path
            # below does for it is only its finish. The frames (the user heartbeat) still go out.
            self._finish(decision)
            return
        self._apply_full(decision, since)

    def _apply_full(self, decision: Decision, since: int | None) -> None:
        """:meth:`_apply` for a decision that may switch outputs, change the state, record or
        refuse: the reference the steady path is checked against."""
        # The usual decision switches nothing and has no read-backs: no list is made for it
        # (SR-9.4); ``pending`` holds the decisions of read-backs, in order, when there are.
        pending: list[Decision] | None = None
        fed, outputs, times = 0, self.outputs, self.stop_times
        while True:
            if decision.state is not State.STOPPED:
                times.ended()
            elif self.decision is not None and self.decision.state is not State.STOPPED:
                self._stop_began(decision)
            readbacks: list[ReadBack] = []
            early_ns = self._early.take(readbacks, times) if self._early.written else None
            early_writes = len(readbacks)
            complete = True  # every output named is open and left at its level
            for name, on in decision.outputs.items():
                output = outputs.get(name)
                if output is None or not output.is_open:
                    complete = False
                    continue
                if output.requested == on:
                    continue
                readback = output.set(on, decision.now)
                readbacks.append(readback)
                if not on and times.waiting(name):
                    # When this off write returned (SR-12.1): one clock read per output, on
                    # a stop only, after the write (outputs first, SR-6.1).
                    times.off(readback, self.clock())
            self._applied_outputs = decision.outputs if complete else None
            previous = self.decision
            if (
                readbacks
                and decision.state is State.STOPPED
                and previous is not None
                and previous.state is not State.STOPPED
            ):
                # A change into STOPPED that switched outputs off: the clock when the writes
                # returned, observed only after the frames are sent (SR-6, SR-10).
                # SR-9.5: when the last off write returned, the reflex's if it wrote them all
                only_early = len(readbacks) == early_writes  # nothing written here after it
                off_ns = early_ns if early_ns is not None and only_early else self.clock()
                self._finish(decision)
                start = decision.now if since is None else min(since, decision.now)
                self.timings.stop_to_off.observe(off_ns - start)
            else:
                self._finish(decision)
            if fed < MAX_SETTLE_STEPS:  # bounded: outputs that flap cannot hold the loop
                fed += 1
                if readbacks:
                    settled = [self._feed(self._readback_event(r, decision.now)) for r in readbacks]
                    pending = settled if pending is None else pending + settled
            if not pending:
                return
            decision = pending.pop(0)

    def _stop_began(self, decision: Decision) -> None:
        """A change into STOPPED: time each output that is on from its stop record (SR-12.1)."""
        for record in decision.records:
            if record.state is State.STOPPED and record.previous is not State.STOPPED:
                early = self._early.wrote  # SR-9.5: off already, ahead of this decision
                on = [n for n, o in self.outputs.items() if o.is_open and (o.requested or early(n))]
                self.stop_times.stopped(record, self.sequence_offset + record.sequence, on)
                return

    def _finish(self, decision: Decision) -> None:
        if decision is self.decision:
            return
        self.decision = decision
        if decision.frames:
            self._send(decision.frames, decision.now)
        for record in decision.records:
            self._write_record(record)
        for refusal in decision.refusals:
            if refusal.reason is RefusalReason.RATE_LIMITED:
                self._rate_limited(decision.now)
            else:
                log.info("refused: %s", refusal.message)
        self.listener.decided(decision)
        service = self.service
        if decision.causes is not service.causes or decision.state is not service.state:
            # The status line depends on these two alone; a decision of the cheap path keeps
            # the previous one's (SR-9.4).
            service.decided(decision)

    def _write_record(self, record: Record) -> None:
        """Hand the record to the sink (never waits). The stop itself has already happened
        (outputs first, SR-6); the record follows on the sink's record lane."""
        typed = stop_record(record, self.wall_clock(), self.sequence_offset)
        if self._version_due:
            # The first record of a start (the startup stop) names the build that made it, so
            # a stop record says which version was running (docs/record.md).
            typed = dataclasses.replace(typed, version=__version__)
            self._version_due = False
        entry = typed.json()
        self._in_sink[typed.seq] = typed
        if self.sink is None:  # not started: nothing can be written yet
            self._recorded(Written(entry, "the record sink is not running", dropped=True))
            return
        if not self.sink.record(entry):
            self._take_written()  # the dropped record is pushed in its place in the order
        flight = self.flight
        if flight is not None:
            flight.last_seq = entry["seq"]
            if record.state is State.STOPPED and record.previous is not State.STOPPED:
                # A stop: its window goes to the flight lane, after the record (SR-7.12).
                self.sink.window(flight.window(entry, self.sequence_offset))

    def _take_written(self) -> None:
        if self.sink is not None:
            for written in self.sink.take_written():
                self._recorded(written)

    def _recorded(self, written: Written) -> None:
        """A record is finished. Not written (a full disk, a full queue) is counted and
        logged, never a stop of its own: docs/record.md "A full disk"."""
        if not written.acknowledged:
            self.counters.record_errors += 1
            self.counters.records_dropped += written.dropped
            log.error("stop record not written: %s", written.error)
        self.schedule.recorded(written.entry)  # a pass resets its test's age (SR-12.2)
        seq = written.entry.get("seq")
        typed = self._in_sink.pop(seq, None) if isinstance(seq, int) else None
        if typed is not None:
            self.listener.recorded(typed)

    def _rate_limited(self, now: int) -> None:
        """Count a release or reset refused under the record budget; log the count at most
        once a second (a flood must not become a flood of log lines)."""
        self.counters.rate_limited += 1
        self._limited_unlogged += 1
        if now >= self._next_limit_log:
            log.warning(
                "%d client requests refused: record budget exceeded (docs/safety.md)",
                self._limited_unlogged,
            )
            self._limited_unlogged = 0
            self._next_limit_log = now + LIMIT_LOG_NS

    def _internal_fault(self, now: int, error: Exception) -> None:
        """The loop failed: outputs off directly, then the ``internal`` cause (SR-2)."""
        self.counters.internal_faults += 1
        log.exception("internal fault in the main loop")
        self._applied_outputs = None  # every output driven off here, outside a decision
        for output in self.outputs.values():
            with contextlib.suppress(Exception):
                output.set(False, now)
        with contextlib.suppress(Exception):
            self._apply(self._feed(InternalFault(now, f"{type(error).__name__}: {error}")))
