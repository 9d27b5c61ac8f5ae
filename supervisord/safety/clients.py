"""The clients of the API socket as the safety core sees them (SR-8): their connections and
names, the required clients' heartbeats, their e-stops and holds, and their declarations of a
commanded motion.

Internal to the core, one of the machines :class:`~supervisord.safety.core.SafetyCore`
composes: its handlers apply one client input each and return what they refuse as a value,
:meth:`Clients.lost` and the request methods give the conditions it raises at ``now``,
:meth:`Clients.next_deadline` its next deadline and :meth:`Clients.canonical` its canonical
form (docs/verification.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from supervisord.safety.budget import RecordBudget, Uid
from supervisord.safety.canonical import Clock, clock
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import NAME_PATTERN, ClientSpec, FleetSpec
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.safety.events import (
    Caller,
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Event,
    Request,
)
from supervisord.safety.face import Seen
from supervisord.safety.fleet import Fleet
from supervisord.safety.progress import ProgressBook


@dataclass(slots=True)
class _Unnamed:
    """A request (e-stop or hold) made before hello, filed under its user (choice 11): the
    connections that asked for it and have not released it. With none left it ends, unless
    the user is past its record budget: then it ends once the budget allows (SR-8.5)."""

    uid: Uid
    holders: set[int]


class Clients:
    """The connected clients, the required ones' liveness and every client's requests."""

    def __init__(self, specs: tuple[ClientSpec, ...], fleet: FleetSpec | None = None) -> None:
        # The fleet's agent is a client too (SR-8.19 to SR-8.21): its stops and its console's
        # keepalive, whose deadline is one of the clients' (``expired``, ``next_deadline``).
        self.fleet = Fleet(fleet or FleetSpec())
        self._required = {c.name: c for c in specs}
        self._timeout_ns = {c.name: c.timeout_ns for c in specs}  # read for every input
        self._connections: dict[int, str | None] = {}
        self._by_name: dict[str, int] = {}
        self._beat_ns: dict[str, int | None] = {}  # a required client's last counted heartbeat
        # SR-8.16: only a heartbeat with new progress counts, where the client is bound to it.
        self._progress = ProgressBook(frozenset(c.name for c in specs if c.progress))
        self._ever_connected: set[str] = set()
        self._estops, self._holds = set[str](), set[str]()  # by client name
        self._nonzero: set[str] = set()  # named clients commanding motion now (SR-4.6)
        self._uid_of: dict[int, Uid] = {}  # connection -> the peer's uid (SR-8.5)
        self._unnamed: dict[tuple[Request, str], _Unnamed] = {}  # requests before hello

    # ----------------------------------------------------------------- handlers

    def connected(self, event: ClientConnected) -> Refusal | None:
        if event.connection in self._connections:
            return Refusal(RefusalReason.DUPLICATE_CONNECTION, str(event.connection), event)
        self._connections[event.connection] = None
        self._uid_of[event.connection] = event.uid
        return None

    def hello(self, event: ClientHello) -> Refusal | None:
        """Name a connection; a refusal of ``WRONG_USER`` is one the core records (docs/
        safety.md "Clients bound to a user")."""
        connection, name = event.connection, event.name
        if connection not in self._connections:
            return Refusal(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
        if self._connections[connection] is not None:
            return Refusal(RefusalReason.ALREADY_NAMED, str(self._connections[connection]), event)
        if self._wrong_user(event):
            # Refused before the name is looked up, so an attempt is recorded also while the
            # real client is connected.
            who = "an unknown caller" if event.caller is None else f"uid {event.caller.uid}"
            return Refusal(RefusalReason.WRONG_USER, f"{name} from {who}", event)
        if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
            return Refusal(RefusalReason.BAD_NAME, repr(name)[:60], event)
        if name in self._by_name:
            return Refusal(RefusalReason.NAME_IN_USE, name, event)
        self._connections[connection] = name
        self._by_name[name] = connection
        self._ever_connected.add(name)
        if name in self._required:
            # SR-4: a client's (re)connection is a new start; it must send a heartbeat.
            self._beat_ns[name] = None
            self._progress.restart(name)  # SR-8.16: its counter starts again
        return None

    def heartbeat(self, event: ClientHeartbeat, now: int) -> Refusal | None:
        name, refusal = self._named(event, event.connection)
        if name is None or name not in self._beat_ns:
            return refusal
        stale = self._progress.beat(name, event.progress)
        if stale is None:
            self._beat_ns[name] = now
            return None
        # SR-8.16: a duplicate, a replay or a missing value extends no deadline
        return Refusal(stale, f"{name} progress {event.progress}", event)

    def beat_unchanged(self, event: ClientHeartbeat, now: int) -> bool:
        """Whether ``event`` at ``now`` changes no condition and is refused nothing: from a
        named client, not required, or required and heard within its timeout, without a
        progress value and not bound to one (SR-8.16). A heartbeat that does not is counted
        (its time; the cheap path's test, ``cheap.cheap``)."""
        name = self._connections.get(event.connection)
        if name is None:
            return False  # unknown or before hello: refused (the full path)
        if name not in self._beat_ns:
            return True  # a client no rule waits for: its heartbeat changes nothing
        beat = self._beat_ns[name]
        if (
            beat is None  # the first since hello ends "no heartbeat since hello"
            or now - beat >= self._timeout_ns[name]  # this one ends the timeout
            or event.progress is not None
            or not self._progress.unbound(name)
        ):
            return False
        self._beat_ns[name] = now
        return True

    def command(self, event: ClientCommand) -> Refusal | None:
        """A named client's declaration of its commanded motion (SR-4.6), kept until it
        declares again or its connection ends; before hello it is refused (``NO_HELLO``)."""
        name, refusal = self._named(event, event.connection)
        if name is None:
            return refusal
        if event.nonzero:
            self._nonzero.add(name)
        else:
            self._nonzero.discard(name)
        return None

    def request(self, event: ClientEstop | ClientHold) -> None:
        # An e-stop or hold is always honoured, even before hello: it can only add a reason
        # to stop (SR-0). Before hello it is filed under the user ("#uid<UID>"), held by
        # every connection of that user that asked for it.
        connection = event.connection
        kind = Request.ESTOP if isinstance(event, ClientEstop) else Request.HOLD
        name = self._connections.get(connection)
        if name is None:
            name = self._unnamed_name(connection)
            entry = self._unnamed.setdefault(
                (kind, name), _Unnamed(self._uid_of.get(connection), set())
            )
            entry.holders.add(connection)
        self._requests(kind).add(name)

    def release(self, event: ClientRelease) -> Refusal | None:
        connection, kind = event.connection, event.request
        requests = self._requests(kind)
        name = self._connections.get(connection)
        released = name is not None and name in requests
        if released:
            requests.discard(name)
        unnamed = self._unnamed_name(connection)
        entry = self._unnamed.get((kind, unnamed))
        if entry is not None and connection in entry.holders:
            released = True
            entry.holders.discard(connection)
            if not entry.holders:
                self._end_unnamed(kind, unnamed)
        if not released:
            return Refusal(RefusalReason.NOTHING_TO_RELEASE, kind.value, event)
        return None

    def disconnected(self, event: ClientDisconnected, limited: bool) -> Refusal | None:
        """A connection ends; ``limited``: its user is past its record budget (SR-8.5)."""
        connection = event.connection
        if connection not in self._connections:
            return Refusal(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
        name = self._connections.pop(connection)
        # Requests made before hello end with the last connection that asked for them
        # (nobody else can release them); their stop stays latched. Past the user's record
        # budget the end waits until the budget allows (SR-8.5): the robot stays held or
        # stopped meanwhile, the safe side. Named requests wait for a client of that name.
        for (kind, unnamed), entry in list(self._unnamed.items()):
            entry.holders.discard(connection)
            if not entry.holders and not limited:
                self._end_unnamed(kind, unnamed)
        self._uid_of.pop(connection, None)
        if name is not None:
            del self._by_name[name]
            self._nonzero.discard(name)  # the process commanding it is gone (SR-4.6)
            if name in self._beat_ns:
                self._beat_ns[name] = None
                self._progress.restart(name)
        return None

    def end_due(self, now: int, budget: RecordBudget) -> None:
        """End the deferred requests whose user is within its budget again, charging it the
        record their end makes (SR-8.5)."""
        for kind, name in self._pending_ends():
            uid = self._unnamed[(kind, name)].uid
            if not budget.exhausted(uid, now):
                self._end_unnamed(kind, name)
                budget.charge(uid, now)

    def uid(self, event: Event) -> Uid:
        """Whom the records a client's input causes are charged to (SR-8.5; docs/safety.md
        "How many records the clients may cause"): the user at the other end, whatever its
        connection, name or process, as the kernel reported it."""
        caller = getattr(event, "caller", None)
        if isinstance(caller, Caller):
            return caller.uid
        if isinstance(event, ClientConnected):
            return event.uid
        connection = getattr(event, "connection", None)
        return self._uid_of.get(connection) if isinstance(connection, int) else None

    # ----------------------------------------------------------------- conditions at now

    def lost(self, now: int) -> dict[Cause, Details]:
        """``client_lost`` for each required client not named, not beaten since hello or
        silent for its timeout (SR-2.4, SR-8.1)."""
        lost: dict[Cause, Details] = {}
        for name, spec in self._required.items():
            if name not in self._by_name:
                reason = "disconnected" if name in self._ever_connected else "never connected"
            else:
                beat = self._beat_ns.get(name)
                # SR-8.16: heartbeats that came but did not count are named as such.
                stale = self._progress.stale(name)
                if beat is None:
                    reason = stale or "no heartbeat since hello"
                elif now - beat >= spec.timeout_ns:  # ">=": a beat 500 ms late is too late
                    reason = stale or "timeout"
                else:
                    continue
            lost[Cause(CauseKind.CLIENT_LOST, name)] = make_details(
                [("reason", reason), ("timeout_ms", str(spec.timeout_ms))]
            )
        return lost

    def estops(self) -> dict[Cause, Details]:
        """``client_estop`` for each client (or user, before hello) that asked (SR-2.5)."""
        return {Cause(CauseKind.CLIENT_ESTOP, n): () for n in self._estops}

    def holds(self) -> dict[Cause, Details]:
        """``client_hold`` for each client (or user, before hello) that asked (SR-3)."""
        return {Cause(CauseKind.CLIENT_HOLD, n): () for n in self._holds}

    def commanding(self) -> list[str]:
        """The named clients whose last declaration is a non-zero command (SR-4.6), sorted."""
        return sorted(self._nonzero)

    def expired(self, now: int) -> bool:
        """Whether a required client's timeout falls due at ``now`` or has (the full step
        raises ``client_lost`` then)."""
        timeouts = self._timeout_ns
        for name, beat in self._beat_ns.items():
            if beat is not None and now - beat >= timeouts[name]:
                return True
        return self.fleet.expired(now)  # SR-8.21: the console's keepalive

    def pending(self) -> bool:
        """Whether a request before hello waits for its user's budget to end (SR-8.5)."""
        return any(not entry.holders for entry in self._unnamed.values())

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """A request before hello may wait for its user's budget (SR-8.5)."""
        return True

    def moving(self) -> bool:
        """A deferred end moves with time (SR-8.5): :meth:`pending`, inline (asked for
        every input the cheap path sees, SR-9.4)."""
        for entry in self._unnamed.values():  # noqa: SIM110 -- no generator per input
            if not entry.holders:
                return True
        return False

    def due_by(self, view: Seen) -> bool:
        """A required client's timeout falls due at ``view.now`` or has (SR-8.2)."""
        return self.expired(view.now)

    def next_deadline(self, view: Seen) -> int | None:
        """The earliest time after ``view.now`` at which a deferred request may end (its
        user's budget in ``view.budget``) or a required client's timeout falls due, or
        ``None``."""
        now, budget = view.now, view.budget
        earliest: int | None = None
        for kind, name in self._pending_ends():
            free = budget.free_at(self._unnamed[(kind, name)].uid, now)
            if free is not None and now < free and (earliest is None or free < earliest):
                earliest = free
        timeouts = self._timeout_ns
        for name, beat in self._beat_ns.items():
            if beat is not None:
                due = beat + timeouts[name]
                if now < due and (earliest is None or due < earliest):
                    earliest = due
        console = self.fleet.next_deadline(now)  # SR-8.21
        if console is not None and (earliest is None or console < earliest):
            earliest = console
        return earliest

    def canonical(self, view: Seen) -> tuple[tuple[object, ...], tuple[Clock, ...]]:
        """The facts (as ``(name, value)`` pairs) and clocks of the clients: each required
        client's heartbeat as its age, with its timeout (docs/verification.md)."""
        now = view.now
        fleet_facts, fleet_clocks = self.fleet.canonical(now)
        clocks = (
            tuple(
                clock(f"client:{name}", beat, now, self._timeout_ns[name])
                for name, beat in sorted(self._beat_ns.items())
                if beat is not None
            )
            + fleet_clocks
        )
        facts = (
            ("connections", tuple(sorted(self._connections.items()))),
            ("by_name", tuple(sorted(self._by_name.items()))),
            ("beaten", tuple(sorted((n, b is None) for n, b in self._beat_ns.items()))),
            ("progress", self._progress.canonical()),
            ("ever_connected", tuple(sorted(self._ever_connected))),
            ("client_estops", tuple(sorted(self._estops))),
            ("client_holds", tuple(sorted(self._holds))),
            ("nonzero", tuple(sorted(self._nonzero))),
            ("uid_of", tuple(sorted(self._uid_of.items(), key=lambda item: item[0]))),
            (
                "unnamed",
                tuple(
                    sorted(
                        (kind.value, name, entry.uid, tuple(sorted(entry.holders)))
                        for (kind, name), entry in self._unnamed.items()
                    )
                ),
            ),
            *fleet_facts,
        )
        return facts, clocks

    NOT_CANONICAL = frozenset({"_required", "_timeout_ns"})
    """Attributes ``canonical`` leaves out: the config, and what is computed from it once."""

    # ----------------------------------------------------------------- helpers

    def _wrong_user(self, event: ClientHello) -> bool:
        spec = self._required.get(event.name) if isinstance(event.name, str) else None
        if spec is None or spec.uid is None:
            return False
        return event.caller is None or event.caller.uid != spec.uid

    def _named(self, event: Event, connection: int) -> tuple[str | None, Refusal | None]:
        """The connection's name, or ``None`` with the refusal its input gets."""
        if connection not in self._connections:
            return None, Refusal(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
        name = self._connections[connection]
        if name is None:
            return None, Refusal(RefusalReason.NO_HELLO, str(connection), event)
        return name, None

    def _unnamed_name(self, connection: int) -> str:
        """Where a request before hello is filed (choice 11): under the peer's uid, so that
        no number of connections multiplies its records (SR-8.5); under the connection when
        the uid is not known. '#' cannot appear in a configured name (NAME_PATTERN)."""
        uid = self._uid_of.get(connection)
        return f"#{connection}" if uid is None else f"#uid{uid}"

    def _requests(self, kind: Request) -> set[str]:
        return self._estops if kind is Request.ESTOP else self._holds

    def _end_unnamed(self, kind: Request, name: str) -> None:
        del self._unnamed[(kind, name)]
        self._requests(kind).discard(name)

    def _pending_ends(self) -> list[tuple[Request, str]]:
        """Requests before hello whose connections all closed while their user was past its
        record budget: they end once it allows (SR-8.5)."""
        return [key for key, entry in self._unnamed.items() if not entry.holders]
