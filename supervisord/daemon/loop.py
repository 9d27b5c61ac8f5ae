"""The one loop of ``srcsd``: the turn's order and the apply order; its parts do the rest.

A turn waits on the link, the client socket, the sink, a wake pair and the earliest deadline
(:mod:`~supervisord.daemon.deadlines`), then serves the stop path first: the link to the VSC,
the core's and the outputs' timers, the sink's news, and only then at most
:data:`MAX_CLIENTS_PER_TURN` client descriptors, fewer when the link has more to read or a
deadline has come (SR-10.1, ``docs/safety.md`` "The stop path first"). Each decision is
applied at once: outputs first, then the frames to the VSC, then the records, then the pushes
(SR-6). The user heartbeat, the outputs and the link are served only by this loop, so if it
hangs, the heartbeat stops and the VSC's key-85 watchdog opens its relays (SR-5).

The parts, each told what it needs as arguments and answering with values, none calling back
into the loop, are listed in ``docs/safety.md`` "The loop's parts": the wait (``waiter``), the
link port, the record path (sink, lanes, flight ring: SR-7.7, SR-7.10), the output bank, the
service manager's face, the status (``loop_status``), the refusal log, the stop request, the
deadlines, the internal fault (``internal_fault``) and the answering of the client API
listener's asks (:mod:`~supervisord.daemon.answer`, which this loop answers as its
``Answers``: :meth:`Supervisor.decide`, ``look``, ``check_off``, ``send``).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import logging
from collections.abc import Callable, Mapping, Sequence

from supervisord.api.status import LoopStatus
from supervisord.clock import MONOTONIC, Clock
from supervisord.daemon import answer, heap, signals
from supervisord.daemon.deadlines import next_deadline, stop_path_waits
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.internal_fault import OVERRUN_NS, failed, late
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.listener import Asks, Listener, Snapshot
from supervisord.daemon.loop_status import Counters, loop_status
from supervisord.daemon.maintenance import Schedule
from supervisord.daemon.notify import Notifier
from supervisord.daemon.offcheck import OffCheck
from supervisord.daemon.offcheck import check_off as checked_off
from supervisord.daemon.output_bank import OutputBank, readback_event
from supervisord.daemon.record_path import RecordPath
from supervisord.daemon.refusal_log import RefusalLog
from supervisord.daemon.service_manager import ServiceManager
from supervisord.daemon.stop_request import StopRequest
from supervisord.daemon.stoptimes import StopTimes
from supervisord.daemon.timings import Timings
from supervisord.daemon.waiter import Waiter
from supervisord.links.base import Backoff, Link
from supervisord.outputs.base import Output
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message, VscHeartbeat
from supervisord.record.jsonl import RecordWriter
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event, LinkBroken, Shutdown, Tick, VscReceived
from supervisord.safety.transitions import State

__all__ = ["MAX_CLIENTS_PER_TURN", "OVERRUN_NS", "Counters", "Listener", "Supervisor"]

log = logging.getLogger("srcsd")

MAX_SETTLE_STEPS = 8  # output read-backs fed back to the core per input, at most
MAX_CLIENTS_PER_TURN = 4  # client descriptors served per turn, at most (docs/safety.md)


class Supervisor:
    """The daemon's state and loop. ``run`` returns the process exit status. It answers the
    listener's asks itself (:class:`~supervisord.daemon.answer.Answers`: :meth:`decide`,
    :meth:`look`, :meth:`check_off`, :meth:`send`)."""

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
        self.listener = listener or Listener()
        # READY, STATUS, WATCHDOG and STOPPING, and when the watchdog is due (SR-0.2, SR-6.5).
        self.service = ServiceManager(notifier or Notifier({}))
        self.clock = clock
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
        self.core: SafetyCore | None = None
        self.decision: Decision | None = None
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
        """What ``status`` says about the daemon itself at ``now`` (the loop's clock), from its
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

    # ----------------------------------------------------------------- start and stop

    def start(self) -> Decision:
        """Outputs off before anything else, then the core, then the link (SR-6).

        Returns the first decision. An output that cannot be acquired (busy, missing, not
        permitted) is ``output_fault:NAME``: the daemon stays up, STOPPED, says so, and tries
        again with a backoff, because a supervisor that exits holds nothing and reports nothing.
        Once acquired (off), the fault's condition clears; its stop waits for a re-arm (SR-4).
        """
        now = self.clock()
        self.counters.started_ns = self.port.since_ns = now
        self.schedule.start(self.records.wall_clock(), now)  # the passes read from the record
        sink_fd = self.records.start()
        events = self.bank.open(now)
        self.core = core = SafetyCore(self.safety, now)
        self.records.began(now)  # a flight window can start from here
        self._apply(core.decision)  # the startup decision, with the first record
        for event in events:
            self.decide(event)
        self.decide(self.port.open(now))
        self.waiter.start(sink_fd)
        decision = self.decision or core.decision  # the last applied (never None here)
        self.service.ready(now, decision)  # the startup decision applied: outputs off
        return decision

    def request_stop(self, signum: int | None = None) -> None:
        """Ask the loop to end (from a signal handler: only sets a flag and wakes the loop).
        The first signal asked for decides the exit status (SR-6.6)."""
        self.stop.ask(signum)
        self.waiter.wake()

    def shutdown(self) -> None:
        """All outputs off, then release the link; then the stop's record; drain the record
        (every queued record written and fsynced, and pushed to subscribers, within the sink's
        deadline), then the socket (SIGTERM path)."""
        self.service.stopping()
        self.bank.all_off(self.clock(), close=True)
        self.port.close()
        # Then the ``shutdown:REASON`` stop's record, after the outputs (SR-7.14): REASON is
        # the signal that asked for the exit, ``requested`` without one, ``error`` when
        # ``run`` raised. The core makes it, so its ``seq`` continues the file's and a replay
        # makes it again; the outputs and the link are closed by now, so the decision switches
        # and sends nothing. No core (its start failed): no sequence to continue.
        if self.core is not None:
            with contextlib.suppress(Exception):
                self.decide(Shutdown(self.clock(), self.stop.reason()))
        # The records first, with a deadline well inside the unit's stop timeout, then
        # pushed; then journal copies and log lines, best effort (SR-7.7).
        with contextlib.suppress(Exception):  # the sockets and the link are closed whatever
            self._recorded(self.records.drain())
        self.records.close()
        self.listener.close()
        self.waiter.close()
        self.service.close()

    def run(self) -> int:
        """Start, loop until a stopping signal, shut down. Every signal that would end the
        process ends it this way, outputs off and the record drained, except those with a
        purpose of their own (SR-6.6, :mod:`~supervisord.daemon.signals`). Exit status 0
        after SIGTERM or SIGINT, 128 + N after another signal N."""
        previous = signals.install(self.request_stop)
        try:
            self.start()
            sink = self.records.sink
            if sink is not None:
                # Log lines leave the loop through the sink too: a slow stderr or journald
                # must not hold the loop (SR-7.5).
                sink.capture_logging(logging.getLogger())
            heap.settle()  # no full scan of start-up's objects in the loop (SR-9.1, SR-9.4)
            stop = self.stop
            while not stop.asked:
                self.step()
            stop.log()  # before the shutdown: the sink drains it with the records
        finally:
            try:
                # A second signal during the shutdown changes nothing: the handlers stay
                # until the outputs are off and the record is drained.
                self.shutdown()
            finally:
                signals.restore(previous)
        return self.stop.exit_status()

    # ----------------------------------------------------------------- the turn

    def step(self) -> None:
        """Wait for the next input or deadline, then serve, in this order: the link to the
        VSC, the core's and the outputs' timers, the record sink's news, and at most
        :data:`MAX_CLIENTS_PER_TURN` client descriptors (SR-10.1; docs/safety.md "The stop
        path first"). Each input is stamped with the clock read when it was read."""
        before = self.clock()
        # Before the wait: never between an input and its outputs.
        self.records.rebase(self.core, before)
        link = self.port.link
        link_fd = link.fileno() if link.is_open else None  # once, for the deadline and the watch
        core_deadline = self.decision.next_deadline if self.decision else before
        deadline = next_deadline(
            before, core_deadline, link_fd, self.port, self.bank, self.service, self.listener
        )
        waiter = self.waiter
        waiter.watch(link_fd, self.listener.descriptors(before))
        ready = waiter.wait(max(0.0, (deadline - before) / 1e9))
        now = self.clock()
        try:
            core_deadline = self.decision.next_deadline if self.decision else now
            if now - core_deadline > OVERRUN_NS:
                self.decide(late(now, core_deadline))
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
                self._recorded(self.records.take_written())
            if clients:
                self._serve_clients(clients)
            work = self.listener.settle(self.clock())
            if work is not None:  # the usual turn has none: no call (SR-9.4)
                answer.serve(work, self)
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
            self._serve(listener.handle(fd, readable, writable, self.clock()))
        for served, (fd, mask) in enumerate(ordered):
            if served >= MAX_CLIENTS_PER_TURN or (served and self._stop_path_waits()):
                return  # the rest stay ready: the next turn serves them
            waiter.cursor = fd
            readable, writable = waiter.readiness(fd, mask)
            # The clock read right before the read: the time this client input was read (SR-2).
            self._serve(listener.handle(fd, readable, writable, self.clock()))

    def _stop_path_waits(self) -> bool:
        core_deadline = self.decision.next_deadline if self.decision is not None else None
        return stop_path_waits(self.clock, core_deadline, self.port.link)

    def _serve(self, work: Asks | None) -> None:
        answer.serve(work, self)

    def _due(self, now: int) -> None:
        """Whatever is due at ``now``, in this order: the core's deadline, the outputs' duties,
        the listener's, a link reopen, the systemd watchdog."""
        if self.decision is not None and now >= self.decision.next_deadline:
            # A stop at a deadline (a link or client timeout) started at the deadline, not
            # when the loop woke: its stop-to-off counts the wake-up too (SR-9.2).
            self._apply(self._feed(Tick(now)), since=self.decision.next_deadline)
        bank = self.bank
        if bank.ticking or bank.acquiring:
            for event in bank.due(now):  # each applied before the next duty (SR-6)
                self.decide(event)
        listener_deadline = self.listener.next_deadline()
        if listener_deadline is not None and now >= listener_deadline:
            answer.serve(self.listener.due(now), self)
        port = self.port
        if self.waiter.link_fd is None and not port.link.is_open and now >= port.next_attempt:
            # (A link watched this turn was open: one that broke in it has just set its backoff.)
            self.decide(port.open(now))
        service = self.service
        if service.next_watchdog is not None and now >= service.next_watchdog:
            service.watchdog(now)

    def _receive(self) -> None:
        """What the link brought, each message fed and applied in its order."""
        got = self.port.receive()
        if isinstance(got, LinkBroken):
            self.decide(got)
            return
        now, received = got
        heartbeat = False
        received_by, flight, core = self.listener.received, self.records.flight, self.core
        heard = self.bank.heard
        assert core is not None
        for item in received:
            kind = type(item)
            if kind is VscHeartbeat:  # SR-9.5: a stop's outputs off before the full step
                heard(item, now, core)  # type: ignore[arg-type]
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

    # ----------------------------------------------------------------- the listener's asks

    def decide(self, event: Event) -> Decision:
        """``event`` fed to the core and its decision applied at once (SR-6): the answer to an
        event the listener asks, and the loop's own way to feed one."""
        decision = self._feed(event)
        self._apply(decision)
        return decision

    def look(self, now: int) -> Snapshot:
        """The loop at ``now`` for the listener: its status and the stops' measured times."""
        return Snapshot(self.snapshot(now), self.bank.stop_times)

    def check_off(self, now: int) -> OffCheck:
        """SR-8.20: every output off written off again and read back, for a fleet stop's
        acknowledgement; a read-back that disagrees goes to the core as any (SR-6)."""
        checked = checked_off(self.bank.outputs, self.clock, self.records.sequence_offset)
        for readback in checked.faults:
            self.decide(readback_event(readback, checked.checked_ns))
        return checked

    def send(self, frames: tuple[Message, ...], now: int) -> None:
        """``frames`` to the VSC; a link that breaks on them is fed as broken."""
        broken = self.port.send(frames, now)
        if broken is not None:
            self.decide(broken)

    # ----------------------------------------------------------------- decisions

    def _feed(self, event: Event) -> Decision:
        """Every input of the core goes through here, and into the flight recorder's ring (a
        reference appended and counted: SR-7.10)."""
        assert self.core is not None
        flight = self.records.flight
        if flight is not None:
            flight.inputs.append(event)
            flight.count += 1
        return self.core.handle(event)

    def _apply(self, decision: Decision, since: int | None = None) -> None:
        """Outputs first, then frames, then records and status (SR-6).

        Setting outputs yields read-backs, which go back to the core; every decision that
        comes of them is applied in turn, so none of their records is lost (a read-back fault
        is a stop of its own, SR-7). ``since`` is when the input (or deadline) that led to
        ``decision`` was read (its ``now`` if not given), for the stop-to-off histogram."""
        previous = self.decision
        if (
            previous is not None
            and decision.state is previous.state
            and not decision.records
            and not decision.refusals
            and self.steady_path
            and self.bank.unchanged(decision.outputs)  # SR-9.5: hands on the reflex's writes
        ):
            # The steady path (SR-9.4): the same levels as the last decision set, every output
            # already at them (nothing else has driven one since, the bank says), the same
            # state (the stop times were told already) and nothing to record or refuse: what
            # the full path below does for it is only its finish. The frames (the user
            # heartbeat) still go out.
            self._finish(decision)
            return
        self._apply_full(decision, since)

    def _apply_full(self, decision: Decision, since: int | None) -> None:
        """:meth:`_apply` for a decision that may switch outputs, change the state, record or
        refuse: the reference the steady path is checked against."""
        # The usual decision switches nothing and has no read-backs: no list is made for it
        # (SR-9.4); ``pending`` holds the decisions of read-backs, in order, when there are.
        pending: list[Decision] | None = None
        fed, bank = 0, self.bank
        times = bank.stop_times
        while True:
            previous = self.decision
            stopping = (
                decision.state is State.STOPPED
                and previous is not None
                and previous.state is not State.STOPPED
            )
            if decision.state is not State.STOPPED:
                times.ended()
            elif stopping:  # time each output that is on from its stop record (SR-12.1)
                times.began(decision.records, self.records.sequence_offset, bank.on)
            readbacks, off_ns = bank.apply(decision, stopping)  # outputs first (SR-6)
            self._finish(decision)
            if off_ns is not None:
                # A change into STOPPED that switched outputs off: the clock when the writes
                # returned, observed only after the frames are sent (SR-6, SR-10).
                start = decision.now if since is None else min(since, decision.now)
                self.timings.stop_to_off.observe(off_ns - start)
            if fed < MAX_SETTLE_STEPS:  # bounded: outputs that flap cannot hold the loop
                fed += 1
                if readbacks:
                    settled = [self._feed(readback_event(r, decision.now)) for r in readbacks]
                    pending = settled if pending is None else pending + settled
            if not pending:
                return
            decision = pending.pop(0)

    def _finish(self, decision: Decision) -> None:
        if decision is self.decision:
            return
        self.decision = decision
        if decision.frames:
            self.send(decision.frames, decision.now)
        if decision.records:
            write = self.records.write
            for record in decision.records:
                # Records after the outputs and the frames (SR-6); one the sink cannot take
                # comes back finished at once, in its place in the order.
                finished = write(record)
                if finished:
                    self._recorded(finished)
        if decision.refusals:  # the rate-limited counted, logged once a second (SR-8.5)
            self.refusals.decided(decision)
        self.listener.decided(decision)
        service = self.service
        if decision.causes is not service.causes or decision.state is not service.state:
            # The status line depends on these two alone; a decision of the cheap path keeps
            # the previous one's (SR-9.4).
            service.decided(decision)

    def _recorded(self, finished: Sequence[StopRecord]) -> None:
        """Records finished (on disk, or counted as not written), in record order: a pass
        resets its test's age (SR-12.2), and each is pushed to subscribers (SR-7.4)."""
        for record in finished:
            self.schedule.recorded(record)
            self.listener.recorded(record)

    def _internal_fault(self, now: int, error: Exception) -> None:
        """The loop failed: outputs off directly, then the ``internal`` cause (SR-2)."""
        fault = failed(now, error, self.counters)  # counted and logged
        self.bank.all_off(now)  # outside a decision
        with contextlib.suppress(Exception):
            self.decide(fault)
