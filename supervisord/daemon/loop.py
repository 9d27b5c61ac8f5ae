"""The one loop of ``srcsd``: the turn's order and the apply order; its parts do the rest.

A turn waits on the link, the client socket, the sink, a wake pair and the earliest deadline
(:mod:`~supervisord.daemon.deadlines`), then serves the stop path first: the link to the VSC,
the core's and the outputs' timers, the sink's news, and only then at most
:data:`MAX_CLIENTS_PER_TURN` client descriptors, fewer when the link has more to read or a
deadline has come (SR-10.1, ``docs/safety.md`` "The stop path first"). Each decision is
applied at once: outputs first, then the frames to the VSC, then the records, then the pushes
(SR-6). The user heartbeat, the outputs and the link are served only by this loop, so if it
hangs, the heartbeat stops and the VSC's key-85 watchdog opens its relays (SR-5).

The parts are built by :class:`~supervisord.daemon.parts.Parts` (``docs/safety.md`` "The
loop's parts"), each told what it needs and answering with values, none calling back into the
loop; the loop answers the client API listener's asks (:mod:`~supervisord.daemon.answer`). The
start, the run and the shutdown are above it, in :mod:`~supervisord.daemon.lifecycle`.
"""

from __future__ import annotations

import contextlib
import select
from collections.abc import Sequence

from supervisord.daemon import answer
from supervisord.daemon.deadlines import next_deadline, stop_path_waits
from supervisord.daemon.internal_fault import OVERRUN_NS, failed, late
from supervisord.daemon.listener import Listener, Snapshot
from supervisord.daemon.loop_status import Counters
from supervisord.daemon.offcheck import OffCheck
from supervisord.daemon.offcheck import check_off as checked_off
from supervisord.daemon.output_bank import readback_event
from supervisord.daemon.parts import Parts
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message, VscHeartbeat
from supervisord.record.stop import StopRecord
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event, LinkBroken, Tick, VscReceived
from supervisord.safety.transitions import State

__all__ = ["MAX_CLIENTS_PER_TURN", "OVERRUN_NS", "Counters", "Listener", "Supervisor"]

MAX_SETTLE_STEPS = 8  # output read-backs fed back to the core per input, at most
MAX_CLIENTS_PER_TURN = 4  # client descriptors served per turn, at most (docs/safety.md)


class Supervisor(Parts):
    """The daemon's loop over its parts: a turn (:meth:`step`) and the apply order. Of its
    own it holds the core and the last decision applied. It answers the listener's asks
    itself (:class:`~supervisord.daemon.answer.Answers`: :meth:`decide`, :meth:`look`,
    :meth:`check_off`, :meth:`send`)."""

    steady_path = True
    """Apply a decision that changes nothing the full path would act on without it (the
    decisions of the core's cheap path, 90 a second in RUN): :meth:`_apply`. The full path is
    the reference: ``tests/daemon/test_steady_path.py`` switches this off on one of two loops
    fed the same inputs and checks that both do the same (SR-9.4)."""

    core: SafetyCore | None = None  # made by the start (lifecycle.start, via begin)
    decision: Decision | None = None  # the last decision applied

    def begin(self, core: SafetyCore) -> None:
        """``core`` decides from now on; its start-up decision applied (the first record, the
        outputs off: SR-6). Called once, by :func:`~supervisord.daemon.lifecycle.start`."""
        self.core = core
        self._apply(core.decision)

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
            # The link's epoll mask (0: not ready), handed to the port: a hang-up with nothing
            # to read is a break without a read (SR-9.8, link_port.HUNG_UP).
            if not ready:  # a deadline's turn: nothing to sort (SR-9.4)
                received, sink_ready, clients = 0, False, None
            elif len(ready) == 1 and ready[0][0] == waiter.link_fd:  # a frame's turn: the same
                received, sink_ready, clients = ready[0][1], False, None
            else:  # the sink's is taken after the timers
                received, sink_ready, clients = waiter.sort(ready)
            if received:
                self._receive(received)
            elif waiter.link_fd is None and link.is_open and link.fileno() is None:
                received = select.EPOLLIN  # a link without a descriptor is polled
                self._receive(received)
            # The timers at the time the wait returned, or after the read when there was one
            # (its work took time): one clock read fewer on a timer's turn (SR-9.4).
            self._due(self.clock() if received else now)
            if sink_ready:
                # Only when the sink said so (its socket is readable once a record is
                # finished): not a system call per turn (SR-9.4).
                self.recorded(self.records.take_written())
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
        waiter, listener, clock = self.waiter, self.listener, self.clock
        first, ordered = waiter.order(ready, listener.urgent())
        for fd, mask in first:
            readable, writable = waiter.readiness(fd, mask)
            answer.serve(listener.handle(fd, readable, writable, clock()), self)
        for served, (fd, mask) in enumerate(ordered):
            if served >= MAX_CLIENTS_PER_TURN:
                return  # the rest stay ready: the next turn serves them
            if served:
                decision = self.decision
                deadline = decision.next_deadline if decision is not None else None
                if stop_path_waits(clock, deadline, self.port.link):
                    return
            waiter.cursor = fd
            readable, writable = waiter.readiness(fd, mask)
            # The clock read right before the read: the time this client input was read (SR-2).
            answer.serve(listener.handle(fd, readable, writable, clock()), self)

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
            opened = port.open(now)
            if opened is not None:  # None: its prepare or last close is under way
                self.decide(opened)
        service = self.service
        if service.next_watchdog is not None and now >= service.next_watchdog:
            service.watchdog(now)

    def _receive(self, events: int) -> None:
        """What the link brought, each message fed and applied in its order (``events``:
        epoll's mask for the link's descriptor)."""
        got = self.port.receive(events)
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
                    self.recorded(finished)
        if decision.refusals:  # the rate-limited counted, logged once a second (SR-8.5)
            self.refusals.decided(decision)
        self.listener.decided(decision)
        service = self.service
        if decision.causes is not service.causes or decision.state is not service.state:
            # The status line depends on these two alone; a decision of the cheap path keeps
            # the previous one's (SR-9.4).
            service.decided(decision)

    def recorded(self, finished: Sequence[StopRecord]) -> None:
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
