"""The API server with the daemon's own listener and a real safety core, over real Unix sockets:
the core judges every ``hello`` and the server answers with its codes (docs/api.md "hello"),
and every end of a connection reaches the core, in order, from the server's one queue."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from supervisord.api.replies import StatusReply, read_reply
from supervisord.api.server import Result, ServerConfig
from supervisord.daemon import answer
from supervisord.daemon.api_listener import ApiListener
from supervisord.daemon.listener import Asks, Snapshot
from supervisord.daemon.offcheck import OffCheck
from supervisord.daemon.stoptimes import StopTimes
from supervisord.protocol.messages import Joystick, Message
from supervisord.safety.config import ClientSpec, SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import ClientDisconnected, ClientHeartbeat, Event
from tests.api.samples import LOOP
from tests.api.test_api_server import READ, WRITE, Loop, Peer


class Judged(Loop):
    """The daemon's loop in miniature with what ``srcsd`` runs behind the socket: the real
    :class:`ApiListener` and a real :class:`SafetyCore` (no link, no outputs). One turn is
    the loop's order: the ready descriptors, what is due, then the end-of-turn ``settle``."""

    def __init__(self, config: ServerConfig, safety: SafetyConfig | None = None) -> None:
        super().__init__(config)
        self.core = SafetyCore(safety or SafetyConfig(), self.clock())
        self.listener = ApiListener(self.server)
        self.listener.decided(self.core.decision)
        self.decisions: list[Decision] = []
        self.events: list[Event] = []
        # What the loop shows the listener: a fixed status, no stops measured.
        self.stop_times = StopTimes()

    # What answers the listener's asks (``supervisord.daemon.answer.Answers``), served by
    # the daemon's own ``answer.serve``: the asks' order and the kind of each answer are the
    # daemon's code, not a copy of it.

    def decide(self, event: Event) -> Decision:
        self.events.append(event)
        decision = self.core.handle(event)
        self.decisions.append(decision)
        self.listener.decided(decision)
        return decision

    def look(self, now: int) -> Snapshot:
        """What the loop says about itself: a fixed status, there being no daemon behind."""
        return Snapshot(LOOP, self.stop_times)

    def check_off(self, now: int) -> OffCheck:
        return OffCheck((), now, 0)  # no outputs behind

    def send(self, frames: tuple[Message, ...], now: int) -> None:
        """No VSC behind: nothing to send."""

    def serve(self, work: Asks | None) -> None:
        answer.serve(work, self)

    def turn(self, timeout: float = 0.0) -> list[Result]:
        self.sync()
        for key, mask in self.selector.select(timeout):
            readable, writable = bool(mask & READ), bool(mask & WRITE)
            self.serve(self.listener.handle(key.fd, readable, writable, self.clock()))
        if (due := self.listener.next_deadline()) is not None and self.clock() >= due:
            self.serve(self.listener.due(self.clock()))
        self.serve(self.listener.settle(self.clock()))
        return []

    def refusals(self) -> list[str]:
        return [r.reason.name for d in self.decisions for r in d.refusals]


@pytest.fixture
def judged(tmp_path: Path) -> Iterator[Judged]:
    loop = Judged(ServerConfig(tmp_path / "api.sock", max_clients=3, max_output=4096))
    yield loop
    loop.close()


def test_hello_rules_are_the_cores_and_keep_their_codes(
    judged: Judged, peers: Callable[[], Peer]
) -> None:
    """SR-8: a heartbeat before hello gets not_hello, a second hello already_named, a name in
    use name_in_use (both the core's refusals, sent with the codes docs/api.md gives them);
    the name is free again once its connection ends."""
    first, second = peers(), peers()
    assert second.ask(judged, {"op": "heartbeat"})["code"] == "not_hello"
    assert first.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    again = first.ask(judged, {"op": "hello", "name": "other", "id": 7})
    assert (again["code"], again["op"], again["id"]) == ("already_named", "hello", 7)
    assert second.ask(judged, {"op": "hello", "name": "nav"})["code"] == "name_in_use"
    assert judged.refusals() == ["ALREADY_NAMED", "NAME_IN_USE"]
    assert first.ask(judged, {"op": "heartbeat"})["ok"] is True
    first.close()
    judged.until(lambda: len(judged.server.clients()) == 1)
    assert second.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    assert second.ask(judged, {"op": "heartbeat"})["ok"] is True
    assert judged.refusals() == ["ALREADY_NAMED", "NAME_IN_USE"]


def test_requests_after_a_hello_in_one_write_see_its_answer(
    judged: Judged, peers: Callable[[], Peer]
) -> None:
    """SR-8: a hello, a heartbeat and an e-stop in one write: the two after the hello are taken
    after the core named the connection (ok, ok; the client's own e-stop); after a refused
    hello the connection is still unnamed (not_hello). Sent once the callers' login name is
    known: before, an e-stop would be served at once, ahead of the hello (SR-10.3)."""
    peer, other = peers(), peers()
    judged.until(lambda: [c.caller.name for c in judged.server.clients()] == ["root", "root"])
    peer.send(b'{"op":"hello","name":"nav"}\n{"op":"heartbeat"}\n{"op":"estop"}\n')
    assert [r["ok"] for r in peer.read(judged, 3)] == [True, True, True]
    assert "client_estop:nav" in judged.core.decision.active_names
    other.send(b'{"op":"hello","name":"nav"}\n{"op":"heartbeat"}\n')
    assert [r["code"] for r in other.read(judged, 2)] == ["name_in_use", "not_hello"]


def test_a_client_dropped_while_pushing_frees_its_name_before_the_next_hello(
    judged: Judged, peers: Callable[[], Peer]
) -> None:
    """SR-8.4, SR-8.1: a subscriber named ``nav`` that stops reading is dropped when a push
    overflows its buffer (the VSC's traffic, served before the clients in a turn); a new
    connection's hello as ``nav`` read in that same turn is accepted by the core, and the
    connection is ``nav`` for the core and the server alike (its heartbeat is taken). Before
    the server queued every end, the end of a connection dropped while pushing reached the
    core only at the end of the turn: the core refused the hello (name in use) while the
    server had named the connection, and its heartbeats were refused from then on."""
    stalled, newcomer = peers(), peers()
    assert stalled.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    assert stalled.ask(judged, {"op": "subscribe", "topics": ["joystick"]})["ok"] is True
    judged.turn()
    newcomer.send({"op": "hello", "name": "nav", "id": 1})  # read in the next turn
    # The start of that turn: the VSC's messages, pushed until the stalled client is dropped.
    for _ in range(100_000):
        if "nav" not in [c.name for c in judged.server.clients()]:
            break
        judged.listener.received(Joystick(), judged.clock())
    assert [c.name for c in judged.server.clients()] == [None]
    (hello,) = newcomer.read(judged)
    assert hello == {"ok": True, "op": "hello", "id": 1}
    assert newcomer.ask(judged, {"op": "heartbeat"})["ok"] is True
    assert judged.refusals() == []
    assert sum(isinstance(e, ClientDisconnected) for e in judged.events) == 1


def test_every_end_reaches_the_core_once(judged: Judged, peers: Callable[[], Peer]) -> None:
    """SR-8.1: connections ended every way (closed by the peer, dropped for not reading)
    free their names in the core: each name can be taken again."""
    names = ["a", "b"]
    ended = [peers() for _ in names]
    for peer, name in zip(ended, names, strict=True):
        assert peer.ask(judged, {"op": "hello", "name": name})["ok"] is True
    assert ended[1].ask(judged, {"op": "subscribe", "topics": ["joystick"]})["ok"] is True
    ended[0].close()
    for _ in range(100_000):
        if len(judged.server.clients()) < 2:
            break
        judged.listener.received(Joystick(), judged.clock())
    judged.until(lambda: judged.server.clients() == ())
    assert sum(isinstance(e, ClientDisconnected) for e in judged.events) == 2
    for name in names:
        fresh = peers()
        assert fresh.ask(judged, {"op": "hello", "name": name})["ok"] is True, name
    assert judged.refusals() == []


def test_status_says_each_connections_command_until_it_ends(
    judged: Judged, peers: Callable[[], Peer]
) -> None:
    """SR-4.6, SR-8: ``status``, built by the listener from the loop's snapshot and taken from
    the server's one queue, says that a client's connection declared a non-zero command; the
    declaration ends with its connection: the same name on a new connection is at zero."""

    def commands(asker: Peer) -> list[tuple[str, bool]]:
        status = read_reply(asker.ask(judged, {"op": "status", "id": 3}))
        assert isinstance(status, StatusReply)
        assert (status.id, status.daemon.loop) == (3, LOOP)
        return [(c.name, c.command_nonzero) for c in status.daemon.clients]

    nav, watcher = peers(), peers()
    assert nav.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    assert commands(watcher) == [("nav", False)]
    assert nav.ask(judged, {"op": "command", "nonzero": True})["ok"] is True
    assert commands(watcher) == [("nav", True)]
    nav.close()
    judged.until(lambda: len(judged.server.clients()) == 1)
    assert commands(watcher) == []
    again = peers()
    assert again.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    assert commands(watcher) == [("nav", False)]


def test_a_heartbeat_with_stale_progress_is_refused_with_its_reason(tmp_path: Path) -> None:
    """SR-8.16: through the real listener and core, a required client's heartbeat whose
    progress repeats the last is refused (``refused``, reason ``stale_progress``), one ahead is
    ok, one without a value after that is refused (``no_progress``), and a value out of range
    is ``bad_request`` before the core sees it."""
    safety = SafetyConfig(clients=(ClientSpec("nav"),))
    loop = Judged(ServerConfig(tmp_path / "api.sock", max_clients=3), safety)
    nav = Peer(tmp_path / "api.sock")
    try:
        assert nav.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
        assert nav.ask(loop, {"op": "heartbeat", "progress": 4294967295})["ok"] is True
        assert nav.ask(loop, {"op": "heartbeat", "progress": 0})["ok"] is True
        again = nav.ask(loop, {"op": "heartbeat", "progress": 0})
        assert (again["ok"], again["code"], again["reason"]) == (False, "refused", "stale_progress")
        plain = nav.ask(loop, {"op": "heartbeat"})
        assert (plain["code"], plain["reason"]) == ("refused", "no_progress")
        beats = [e for e in loop.events if isinstance(e, ClientHeartbeat)]
        assert [e.progress for e in beats] == [4294967295, 0, 0, None]
        wrong = nav.ask(loop, {"op": "heartbeat", "progress": 2**32})
        assert wrong["code"] == "bad_request"
        assert "progress" in wrong["error"]
        assert len([e for e in loop.events if isinstance(e, ClientHeartbeat)]) == 4
    finally:
        nav.close()
        loop.close()


def test_each_request_is_answered_before_the_next_is_taken(
    judged: Judged, peers: Callable[[], Peer]
) -> None:
    """SR-6, SR-8: an e-stop, a status and a hold in one write: each request's decision is
    applied (its state push out) and the request answered before the next is fed, so the
    status sees the e-stop and not the hold, and the bytes come in request order: push, reply,
    status, push, reply."""
    peer = peers()
    judged.until(lambda: [c.caller.name for c in judged.server.clients()] == ["root"])
    assert peer.ask(judged, {"op": "hello", "name": "nav"})["ok"] is True
    assert peer.ask(judged, {"op": "subscribe", "topics": ["state"], "id": 0})["ok"] is True
    peer.read(judged)  # the state as it was, pushed with the subscription
    peer.send(b'{"op":"estop","id":1}\n{"op":"status","id":2}\n{"op":"hold","id":3}\n')
    lines = peer.read(judged, 5)
    kinds = [(line.get("event") or line.get("op"), line.get("id")) for line in lines]
    assert kinds == [("state", None), ("estop", 1), ("status", 2), ("state", None), ("hold", 3)]
    seen = [{c["name"] for c in lines[i]["causes"] if c["active"]} for i in (0, 2, 3)]
    assert "client_estop:nav" in seen[0]
    assert seen[1] == seen[0]  # the status is the e-stop's state, before the hold
    assert any(name.startswith("client_hold") for name in seen[2] - seen[1])


class Unanswered(Judged):
    """A loop that answers a look with the wrong kind (a planted bug in the loop's answering):
    what the listener does then is its own, typed, not an assertion in the loop."""

    def look(self, now: int) -> Snapshot:
        return OffCheck((), now, 0)  # type: ignore[return-value]  # the planted wrong answer


def test_a_status_the_loop_did_not_answer_is_refused_unavailable_and_the_loop_goes_on(
    tmp_path: Path, peers: Callable[[], Peer]
) -> None:
    """SR-6, SR-8: a ``status`` whose look the loop answered with something else is refused
    ``unavailable`` to its client (the listener narrows each answer to its kind: no assert on
    the asks' path); the connection and the next request go on."""
    loop = Unanswered(ServerConfig(tmp_path / "api.sock", max_clients=3, max_output=4096))
    try:
        asker = peers()
        reply = asker.ask(loop, {"op": "status", "id": 4})
        assert (reply["ok"], reply["code"], reply["op"], reply["id"]) == (
            False,
            "unavailable",
            "status",
            4,
        )
        assert asker.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
    finally:
        loop.close()
