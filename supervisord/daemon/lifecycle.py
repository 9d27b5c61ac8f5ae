"""Above the loop: the daemon's start, its run until a stopping signal, and its shutdown.

The order of a life, kept here once for srcsd, the benches and the tests: at the start the
outputs off before anything else, then the core, then the link, then READY (SR-6, SR-0.2); an
output that cannot be acquired is a fault the daemon stays up with (SR-4). The run installs
the stopping signals' handlers, which only ask the loop to end and wake it (SR-6.6,
:mod:`~supervisord.daemon.signals`), turns the loop (:meth:`Supervisor.step
<supervisord.daemon.loop.Supervisor.step>`) until asked, and always shuts down: every output
off, the link released, then the ``shutdown:REASON`` stop's record (SR-7.14), the records
drained within the sink's deadline and pushed (SR-7.7, the SIGTERM path), then the sockets.

These call the loop (its ``step``, ``begin``, ``decide`` and ``recorded``); the loop calls
nothing here.
"""

from __future__ import annotations

import contextlib
import logging
from functools import partial

from supervisord.daemon import heap, signals
from supervisord.daemon.loop import Supervisor
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import Shutdown

START_OPEN_WAIT_S = 1.0
"""How long the start waits for the link's open, made off the loop (``srcsd-open``, SR-9.8),
so that READY comes with the link open as a rule; the loop serves nothing yet, and the
outputs are off. A device whose open takes longer is taken by the loop once it is made."""

__all__ = ["request_stop", "run", "shutdown", "start"]


def start(loop: Supervisor) -> Decision:
    """Outputs off before anything else, then the core, then the link (SR-6); returns the
    last decision applied.

    An output that cannot be acquired (busy, missing, not permitted) is
    ``output_fault:NAME``: the daemon stays up, STOPPED, says so, and tries again with a
    backoff, because a supervisor that exits holds nothing and reports nothing. Once acquired
    (off), the fault's condition clears; its stop waits for a re-arm (SR-4).
    """
    now = loop.clock()
    loop.counters.started_ns = loop.port.since_ns = now
    loop.schedule.start(loop.records.wall_clock(), now)  # the passes read from the record
    sink_fd = loop.records.start()
    events = loop.bank.open(now)
    core = SafetyCore(loop.safety, now)
    loop.records.began(now)  # a flight window can start from here
    loop.begin(core)  # the startup decision applied, with the first record
    for event in events:
        loop.decide(event)
    opened = loop.port.open(now)
    if opened is None:  # the link's prepare is under way: the start waits for it, bounded
        loop.port.settle(START_OPEN_WAIT_S)
        opened = loop.port.open(now)
    if opened is not None:  # None: still under way, the loop asks again
        loop.decide(opened)
    loop.waiter.start(sink_fd)
    decision = loop.decision or core.decision  # the last applied (never None here)
    loop.service.ready(now, decision)  # the startup decision applied: outputs off
    return decision


def request_stop(loop: Supervisor, signum: int | None = None) -> None:
    """Ask the loop to end (from a signal handler: only sets a flag and wakes the loop).
    The first signal asked for decides the exit status (SR-6.6)."""
    loop.stop.ask(signum)
    loop.waiter.wake()


def shutdown(loop: Supervisor) -> None:
    """All outputs off, then release the link; then the stop's record; drain the record
    (every queued record written and fsynced, and pushed to subscribers, within the sink's
    deadline), then the socket (SIGTERM path)."""
    loop.service.stopping()
    loop.bank.all_off(loop.clock(), close=True)
    loop.port.close()
    # Then the ``shutdown:REASON`` stop's record, after the outputs (SR-7.14): REASON is the
    # signal that asked for the exit, ``requested`` without one, ``error`` when ``run``
    # raised. The core makes it, so its ``seq`` continues the file's and a replay makes it
    # again; the outputs and the link are closed by now, so the decision switches and sends
    # nothing. No core (its start failed): no sequence to continue.
    if loop.core is not None:
        with contextlib.suppress(Exception):
            loop.decide(Shutdown(loop.clock(), loop.stop.reason()))
    # The records first, with a deadline well inside the unit's stop timeout, then pushed;
    # then journal copies and log lines, best effort (SR-7.7).
    with contextlib.suppress(Exception):  # the sockets and the link are closed whatever
        loop.recorded(loop.records.drain())
    loop.records.close()
    loop.listener.close()
    loop.waiter.close()
    loop.service.close()


def run(loop: Supervisor) -> int:
    """Start, loop until a stopping signal, shut down. Every signal that would end the
    process ends it this way, outputs off and the record drained, except those with a
    purpose of their own (SR-6.6, :mod:`~supervisord.daemon.signals`). Exit status 0 after
    SIGTERM or SIGINT, 128 + N after another signal N."""
    previous = signals.install(partial(request_stop, loop))
    try:
        start(loop)
        sink = loop.records.sink
        if sink is not None:
            # Log lines leave the loop through the sink too: a slow stderr or journald must
            # not hold the loop (SR-7.5).
            sink.capture_logging(logging.getLogger())
        heap.settle()  # no full scan of start-up's objects in the loop (SR-9.1, SR-9.4)
        stop = loop.stop
        while not stop.asked:
            loop.step()
        stop.log()  # before the shutdown: the sink drains it with the records
    finally:
        try:
            # A second signal during the shutdown changes nothing: the handlers stay until
            # the outputs are off and the record is drained.
            shutdown(loop)
        finally:
            signals.restore(previous)
    return loop.stop.exit_status()
