"""The client API served from the daemon's loop: requests in, replies and pushes out.

Every request that is a safety input goes to the core first; the reply then says "ok", or
carries the core's refusal (e.g. why a reset was not honoured, or ``rate_limited`` past the
client's record budget, docs/safety.md); a ``hello`` is the core's to judge, and its refusal
comes back with the code docs/api.md gives it. State pushes go out with the decision; record
pushes once the record is on disk (``Listener.recorded``). Everything the server reports,
every end of a connection included (a stopped or flooding client dropped while being written
to), is taken from its one queue in one place (``_take``), so no end is lost on the way.
A ``commission`` is answered when its procedure ends (``daemon/commission.py``), a few
seconds later; the loop meanwhile goes on as ever.

The listener never calls into the loop: what it needs of it (an event fed and its decision, a
look at the loop's status and stop times, frames sent to the VSC) it asks as it goes, as the
:data:`~supervisord.daemon.listener.Asks` its ``handle``, ``settle`` and ``due`` return, and the
loop sends back each answer before the work goes on: the same order, and the same bytes, as
when the work called the loop itself.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from supervisord.api.framing import ApiError, ErrorCode
from supervisord.api.ops import RequestId
from supervisord.api.pushes import RecordPush
from supervisord.api.replies import CommissionReply, StatusReply, StopTestReply
from supervisord.api.requests import (
    Command,
    Commission,
    FleetStopRequest,
    Heartbeat,
    Status,
    StopTest,
    Subscribe,
    Topic,
)
from supervisord.api.server import ApiServer, Closed, Received, Result, core_event
from supervisord.api.status import ClientStatus, DaemonStatus, EstopAvailable
from supervisord.api.views import (
    MESSAGE_TOPICS,
    message_push,
    rearm_status,
    refusal_error,
    remote_report,
    state_push,
    state_report,
)
from supervisord.daemon.answer import check_off, look
from supervisord.daemon.availability import estop_available
from supervisord.daemon.commission import Commissioning
from supervisord.daemon.fleet_ack import FleetAcks
from supervisord.daemon.listener import Asks, Listener, Send, Snapshot
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message, RemoteStatus, VscHeartbeat
from supervisord.record.format import stoptest_report
from supervisord.record.stop import StopRecord
from supervisord.safety.availability import DEFAULT_MIN_REMOTE_BATTERY
from supervisord.safety.causes import CauseKind
from supervisord.safety.config import DEFAULT_REARM_HOLD_MS
from supervisord.safety.decision import Decision
from supervisord.safety.events import StopTested
from supervisord.safety.stoptest import LIMIT_MS
from supervisord.timebase import seconds_since


class ApiListener(Listener):
    """``has_key85``: the VSC's link is serial (CAN and HID have no key 85 to commission);
    ``robot``: the configured robot name, for ``status``; ``required``: the required clients'
    names and timeouts (ms), for ``status``; ``min_remote_battery``: ``vsc.min_remote_battery``,
    for ``status``'s ``estop_available`` (SR-8.11); ``rearm_hold_ms``: ``rearm.hold_ms``, for
    ``status``'s ``rearm`` (SR-8.10: when a takeover is accepted). Time comes from the loop,
    as ``now`` (SR-2.11): the listener keeps no clock of its own."""

    def __init__(
        self,
        server: ApiServer,
        *,
        has_key85: bool = True,
        robot: str | None = None,
        required: Mapping[str, int] | None = None,
        min_remote_battery: int = DEFAULT_MIN_REMOTE_BATTERY,
        rearm_hold_ms: int = DEFAULT_REARM_HOLD_MS,
    ) -> None:
        self.server = server
        self.has_key85 = has_key85
        self.robot = robot
        self.required = dict(required or {})
        self.min_remote_battery = min_remote_battery
        self.rearm_hold_ms = rearm_hold_ms
        # For ``status`` (docs/api.md "status"): each connection's last accepted heartbeat,
        # the latest remote status and when it came, and when the current state began.
        self._beats: dict[int, int] = {}
        self._nonzero: dict[int, bool] = {}  # each connection's last declaration (SR-4.6)
        self._remote: tuple[RemoteStatus, int] | None = None
        self._heartbeat: VscHeartbeat | None = None  # the VSC's last, for estop_available
        self._state_since: int | None = None
        self.last: Decision | None = None
        self._commissioning: tuple[Commissioning, Received] | None = None
        self._fleet = FleetAcks(lambda: self.last)  # SR-8.20

    def descriptors(self, now: int) -> Iterable[tuple[int, bool]]:
        return self.server.descriptors(now)

    def urgent(self) -> frozenset[int]:
        return self.server.urgent()  # the operator socket (SR-8.14)

    def handle(self, fd: int, readable: bool, writable: bool, now: int) -> Asks | None:
        self.server.handle(fd, readable, writable, now)
        return self.settle(now)  # what it queued, taken as at the end of a turn

    def settle(self, now: int) -> Asks | None:
        # Ends queued outside handle and due: a client dropped while a push was written.
        result = self.server.take()  # once a turn, mostly with nothing queued (SR-9.4)
        return None if result is None else self._take(now, result)

    def _take(self, now: int, result: Result | None) -> Asks:
        """Every result the server queued, from ``result`` on, in order: the one place they
        are taken. Answering one may queue more (an end while writing the answer): taken in
        the same pass."""
        while result is not None:
            yield from self._result(result, now)
            result = self.server.take()

    def _result(self, result: Result, now: int) -> Asks:
        event = core_event(result, now)
        decision = (yield event) if event is not None else None
        if isinstance(result, Closed):
            self._beats.pop(result.client.connection, None)
            self._nonzero.pop(result.client.connection, None)
        if not isinstance(result, Received):
            return  # Denied was answered by the server; Accepted and Closed need no reply
        request = result.request
        if isinstance(request, Status):
            yield from self._status(result, request, now)
            return
        if isinstance(request, Commission):
            self._begin_commissioning(result, now)
            return
        if isinstance(request, StopTest):
            yield from self._stoptest(result, request, now)
            return
        refusal = (
            next((r for r in decision.refusals if r.trigger == event), None)
            if isinstance(decision, Decision) and decision.refusals  # mostly none (SR-9.4)
            else None
        )
        if refusal is not None:
            self.server.reply_error(result, refusal_error(request, refusal))
        elif isinstance(request, FleetStopRequest) and isinstance(decision, Decision):
            yield from self._fleet_stop(result, request, decision, now)
        else:
            if isinstance(request, Heartbeat):
                self._beats[result.client.connection] = now
            elif isinstance(request, Command):
                self._nonzero[result.client.connection] = request.nonzero
            self.server.reply(result)
        if isinstance(request, Subscribe) and Topic.STATE in request.topics and self.last:
            self.server.send(result.client.connection, state_push(self.last))

    def _status(self, result: Received, request: Status, now: int) -> Asks:
        """A ``status``: a look at the loop, then the reply built from it."""
        snapshot, last = (yield from look(now)), self.last
        if snapshot is None or last is None:  # the loop applied no decision yet
            self.server.reply_error(result, _unanswered(request.OP, request.id))
        else:
            self.server.reply(result, self.status(request, now, snapshot, last))

    def _fleet_stop(
        self, result: Received, request: FleetStopRequest, decision: Decision, now: int
    ) -> Asks:
        """SR-8.20: the acknowledgement is sent after the stop is applied (the loop set the
        outputs when it answered the event), with what they read back now."""
        ack = self._fleet.repeated(request)
        if ack is None:
            check = yield from check_off(now)
            if check is None:
                self.server.reply_error(result, _unanswered(request.OP, request.id))
                return
            ack = self._fleet.acknowledge(request, decision, now, check)
        self.server.reply(result, ack)

    def status(self, request: Status, now: int, snapshot: Snapshot, last: Decision) -> StatusReply:
        """The ``status`` reply (docs/api.md "status"), the one place it is built: the last
        decision, the loop's ``snapshot`` and what the listener saw itself (the clients, the
        remote's last status, the time in the current state). Names passed the server's
        check: nothing here is input the listener cannot trust. ``last``: the last decision."""
        every = self.server.clients()
        connected = {c.name: c.connection for c in every if c.name is not None}
        clients: list[ClientStatus] = []
        for name in sorted(set(self.required) | set(connected)):
            connection = connected.get(name)
            beat = self._beats.get(connection) if connection is not None else None
            clients.append(
                ClientStatus(
                    name=name,
                    required=name in self.required,
                    connected=connection is not None,
                    heartbeat_age_s=seconds_since(now, beat),
                    command_nonzero=connection is not None and self._nonzero.get(connection, False),
                    timeout_ms=self.required.get(name),
                )
            )
        remote = None
        if self._remote is not None:
            message, seen = self._remote
            remote = remote_report(message, seconds_since(now, seen))
        daemon = DaemonStatus(
            robot=self.robot,
            loop=snapshot.status,
            clients=tuple(clients),
            connections=len(every),
            remote=remote,
            in_state_s=seconds_since(now, self._state_since),
        )
        return StatusReply(
            id=request.id,
            report=state_report(last),
            estop_available=self.estop_available(now, last),
            daemon=daemon,
            rearm=rearm_status(last, now, self.rearm_hold_ms),
        )

    def estop_available(self, now: int, last: Decision) -> EstopAvailable:
        """Whether the remote e-stop is available (SR-8.11), from what the listener saw:
        the last decision's causes and proof test, the VSC's last heartbeat and remote status."""
        remote, seen = self._remote if self._remote is not None else (None, None)
        return estop_available(
            now,
            active=(c.cause for c in last.causes if c.active),
            heartbeat=self._heartbeat,
            remote=remote,
            remote_seen=seen,
            prooftest=last.prooftest,
            min_battery=self.min_remote_battery,
        )

    def _stoptest(self, result: Received, request: StopTest, now: int) -> Asks:
        """Judge the presses the client names from the loop's own measurements and record
        the result (SR-12.1); admin rights were checked by the server. The client's part is
        the dialogue and which stops its presses made, never a number."""
        snapshot = yield from look(now)
        if snapshot is None:
            self.server.reply_error(result, _unanswered(request.OP, request.id))
            return
        judged = snapshot.stop_times.result(request.steps, LIMIT_MS)
        if isinstance(judged, str):
            error = ApiError(ErrorCode.UNAVAILABLE, judged, op=request.OP, request_id=request.id)
            self.server.reply_error(result, error)
            return
        yield StopTested(now, result.client.caller, judged)  # the stoptest record
        self.server.reply(result, StopTestReply(id=request.id, stoptest=stoptest_report(judged)))

    def _begin_commissioning(self, result: Received, now: int) -> None:
        """Admin rights were checked by the server; here: is there a VSC to write to?"""
        request = result.request
        why = None
        if not self.has_key85:
            why = "the VSC's link is CAN or HID: there is no key 85 to set"
        elif self.last is None or CauseKind.TRANSPORT_FAULT.value in self.last.active_names:
            why = "there is no link to the VSC"
        elif self._commissioning is not None:
            why = "a commissioning is already running"
        if why is not None:
            error = ApiError(ErrorCode.UNAVAILABLE, why, op=request.OP, request_id=request.id)
            self.server.reply_error(result, error)
            return
        self._commissioning = (Commissioning(result.client.caller, now), result)

    def due(self, now: int) -> Asks | None:
        server_due = self.server.next_deadline()
        server = server_due is not None and now >= server_due
        if not server and self._commissioning is None:
            return None
        return self._due(now, server=server)

    def _due(self, now: int, *, server: bool) -> Asks:
        if server:
            self.server.due(now)
            yield from self._take(now, self.server.take())
        if self._commissioning is None:
            return
        procedure, result = self._commissioning
        if not procedure.finished(now):
            frames = tuple(procedure.due(now))
            if frames:
                yield Send(frames, now)
            return
        self._commissioning = None
        yield procedure.outcome(now)  # recorded by the core, whatever the outcome
        if procedure.key85 != 1:
            read = "no answer" if procedure.key85 is None else procedure.key85
            request = result.request
            error = ApiError(
                ErrorCode.FAILED,
                f"key 85 reads back {read}, not 1",
                op=request.OP,
                request_id=request.id,
                extra={"key85": procedure.key85, "remote_status": procedure.remote_status},
            )
            self.server.reply_error(result, error)
        else:
            reply = CommissionReply(
                id=result.request.id, key85=procedure.key85, remote_status=procedure.remote_status
            )
            self.server.reply(result, reply)

    def next_deadline(self) -> int | None:
        # The server's own (an idle e-stop slot to close, checked when the loop asks for its
        # descriptors) and the commissioning's, whichever comes first.
        server = self.server.next_deadline()
        if self._commissioning is None:
            return server  # the usual case, asked twice a turn (SR-9.4)
        deadlines = [server, self._commissioning[0].next_deadline()]
        due = [d for d in deadlines if d is not None]
        return min(due) if due else None

    def decided(self, decision: Decision) -> None:
        last = self.last
        if last is None or decision.state is not last.state:
            changed = True
            self._state_since = decision.now
        else:
            # The same tuple object is the same causes: the cheap path keeps them (SR-9.4).
            changed = decision.causes is not last.causes and decision.causes != last.causes
        self.last = decision
        if changed and self.server.subscribed(Topic.STATE):
            self.server.broadcast(Topic.STATE, state_push(decision))

    def recorded(self, record: StopRecord) -> None:
        # Pushed once the sink has it on disk (or counted it as not written): a record a
        # subscriber sees is an acknowledged one (SR-7, docs/record.md).
        if self.server.subscribed(Topic.RECORDS):
            self.server.broadcast(Topic.RECORDS, RecordPush(record))

    def received(self, message: Message | HidInput, now: int) -> None:
        # A push is built only when someone subscribed to its topic (SR-9.4).
        if isinstance(message, VscHeartbeat):
            self._heartbeat = message
        elif isinstance(message, HidInput):
            return
        elif isinstance(message, RemoteStatus):
            # Its values stay as the VSC last sent them (PR-2.10): the age says how old.
            self._remote = (message, now)
        if self._commissioning is not None:
            self._commissioning[0].received(message)
        topic = MESSAGE_TOPICS.get(type(message))  # ``message_topic``, a call fewer per input
        if topic is not None and self.server.subscribed(topic):
            self.server.broadcast(topic, message_push(message))  # type: ignore[arg-type]

    def close(self) -> None:
        self.server.close()


def _unanswered(op: str, request_id: RequestId) -> ApiError:
    """The typed refusal of a request whose ask the loop did not answer with its kind: the
    client is told, the loop goes on (SR-6, SR-8; no input may raise in the loop)."""
    return ApiError(
        ErrorCode.UNAVAILABLE, "the daemon's loop did not answer", op=op, request_id=request_id
    )
