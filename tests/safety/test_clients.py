"""Clients on the local socket (SR-8): names, requests and nonsense inputs."""

from __future__ import annotations

from dataclasses import replace

from supervisord.safety import (
    Caller,
    ClientConnected,
    ClientHeartbeat,
    ClientHello,
    ClientSpec,
    RecordNote,
    RefusalReason,
    Request,
    SafetyCore,
    State,
    Transport,
)
from supervisord.safety.budget import RecordBudget
from supervisord.safety.clients import Clients
from supervisord.safety.view import View
from tests.safety.rig import MS, NOBODY, OPERATIONAL, ROBOT, Rig


def test_hello_refusals() -> None:
    """Hello from an unknown connection, a second hello, a taken name and a bad name are each
    refused with their own reason."""
    rig = Rig()
    assert (
        rig.feed(ClientHello(rig.now, 9, "x")).refusals[0].reason
        is RefusalReason.UNKNOWN_CONNECTION
    )
    rig.connect(1)
    assert rig.feed(ClientHello(rig.now, 1, "y")).refusals[0].reason is RefusalReason.ALREADY_NAMED
    rig.connect(2, None)
    assert (
        rig.feed(ClientHello(rig.now, 2, "planner")).refusals[0].reason is RefusalReason.NAME_IN_USE
    )
    assert rig.feed(ClientHello(rig.now, 2, "a b")).refusals[0].reason is RefusalReason.BAD_NAME
    assert rig.connect(1, None).refusals[0].reason is RefusalReason.DUPLICATE_CONNECTION


def test_heartbeat_before_hello_is_refused_and_does_not_count() -> None:
    """A heartbeat from a connection that has not said hello is ignored with a reason."""
    rig = Rig()
    rig.connect(1, None)
    decision = rig.beat(1)
    assert decision.refusals[0].reason is RefusalReason.NO_HELLO
    assert "client_lost:planner" in decision.active_names


def test_estop_before_hello_is_honoured() -> None:
    """An e-stop is never refused: before hello it is filed under ``#<connection>``, the same
    connection can release it, and its stop stays latched."""
    rig = Rig()
    rig.bring_up()
    rig.connect(7, None)
    stopped = rig.estop(7)
    assert stopped.state is State.STOPPED
    assert "client_estop:#7" in stopped.active_names
    released = rig.release(7)
    assert "client_estop:#7" not in released.active_names
    assert "client_estop:#7" in released.latched_names


def test_anonymous_estop_ends_with_its_connection() -> None:
    """SR-1.1, SR-2: an e-stop made before hello ends when its connection closes, and its stop
    stays latched: STOPPED, the drive off, through healthy inputs until a re-arm."""
    rig = Rig()
    rig.bring_up()
    rig.connect(7, None)
    rig.estop(7)
    decision = rig.disconnect(7)
    assert "client_estop:#7" not in decision.active_names
    assert "client_estop:#7" in decision.latched_names
    assert decision.state is State.STOPPED
    later = rig.run_for(1000, OPERATIONAL)  # the VSC healthy, the planner beating
    assert later.state is State.STOPPED
    assert "client_estop:#7" in later.latched_names
    assert later.outputs["drive"] is False


def test_named_estop_survives_a_disconnect_until_that_client_releases() -> None:
    """A named client's e-stop stays active after it disconnects, and a client with the same
    name can release it after reconnecting."""
    rig = Rig()
    rig.bring_up()
    rig.connect(3, "arm")
    rig.estop(3)
    rig.disconnect(3)
    assert "client_estop:arm" in rig.last.active_names
    rig.connect(4, "arm")
    assert "client_estop:arm" not in rig.release(4).active_names


def test_non_required_clients_are_never_lost() -> None:
    """A client not in the config may come and go without raising ``client_lost``."""
    rig = Rig()
    rig.bring_up()
    rig.connect(3, "logger")
    rig.beat(3)
    decision = rig.disconnect(3)
    assert decision.state is State.RUN
    assert not any(name.startswith("client_lost:logger") for name in decision.latched_names)


def test_release_without_a_request_is_refused() -> None:
    """Releasing a request the client does not have is refused and changes nothing."""
    rig = Rig()
    rig.bring_up()
    decision = rig.release(1, Request.HOLD)
    assert decision.refusals[0].reason is RefusalReason.NOTHING_TO_RELEASE
    assert decision.state is State.RUN


def test_a_release_of_hold_does_not_release_the_estop() -> None:
    """A client's hold release leaves its e-stop active."""
    rig = Rig()
    rig.bring_up()
    rig.hold()
    rig.estop()
    decision = rig.release(request=Request.HOLD)
    assert "client_estop:planner" in decision.active_names
    assert decision.state is State.STOPPED
    rig.advance(10)
    assert rig.vsc(OPERATIONAL).state is State.STOPPED


def test_a_bound_name_from_another_user_is_refused_and_recorded() -> None:
    """SR-8.6: a hello under the name of a client bound to uid 1000, from uid 1001 or from a
    caller the kernel did not name, is refused (``wrong_user``) and recorded as a refused
    hello that says who asked; from uid 1000 it names the connection."""
    config = replace(ROBOT, clients=(ClientSpec("planner", uid=1000),))
    rig = Rig(config)
    for connection, caller, who in ((1, NOBODY, "uid 1001"), (2, None, "an unknown caller")):
        rig.connect(connection, name=None)
        decision = rig.feed(ClientHello(rig.now, connection, "planner", caller))
        (refusal,) = decision.refusals
        assert refusal.reason is RefusalReason.WRONG_USER
        assert refusal.detail == f"planner from {who}"
        (record,) = decision.records
        assert record.note is RecordNote.HELLO_REFUSED
        assert record.reason == refusal.message
    owner = Caller(uid=1000, pid=44, name="robot", admin=False)
    rig.connect(3, name=None)
    assert rig.feed(ClientHello(rig.now, 3, "planner", owner)).refusals == ()


def test_a_lost_client_says_whether_it_ever_connected() -> None:
    """SR-2.4: ``client_lost``'s reason tells a required client that never said hello since
    the start from one that did and went away."""
    rig = Rig()
    never = rig.last.cause("client_lost:planner")
    assert never is not None
    assert never.detail("reason") == "never connected"
    rig.bring_up()
    rig.advance(10)
    gone = rig.disconnect().cause("client_lost:planner")
    assert gone is not None
    assert gone.detail("reason") == "disconnected"


def test_inputs_from_an_unknown_connection_are_refused() -> None:
    """SR-8.7: a heartbeat or a goodbye from a connection the core never saw
    connect is refused by name (``unknown_connection``) and changes nothing."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    for decision in (rig.beat(9), rig.disconnect(9)):
        assert [r.reason for r in decision.refusals] == [RefusalReason.UNKNOWN_CONNECTION]
        assert decision.state is State.RUN
        assert not decision.records


def test_a_closed_connection_forgets_its_user() -> None:
    """SR-8.5, SR-2.5: a connection's user is known while it is open; after its goodbye, an
    e-stop under its number (still honoured, SR-0) is filed under the number, not under the
    user it had."""
    rig = Rig()
    rig.bring_up()
    rig.connect(7, name=None, uid=1001)
    assert "client_estop:#uid1001" in rig.estop(7).active_names
    rig.release(7)
    rig.disconnect(7)
    rig.advance(10)
    assert "client_estop:#7" in rig.estop(7).active_names


def test_a_client_that_said_goodbye_sets_no_deadline() -> None:
    """SR-2.4, SR-2.11: after a required client's goodbye its heartbeat's timeout is no
    deadline any more (it is lost already): the next deadline is the VSC's, not a wake-up at
    the timeout of a heartbeat from before the goodbye."""
    can = replace(ROBOT, transport=Transport.CAN, require_watchdog=False)  # no user heartbeat
    rig = Rig(can)
    rig.bring_up()
    rig.advance(10)
    rig.beat()  # the client's last heartbeat: its timeout would fall 500 ms from here
    for _ in range(9):
        rig.advance(50)
        rig.vsc(OPERATIONAL)
    decision = rig.disconnect()
    assert "client_lost:planner" in decision.active_names
    assert decision.next_deadline == rig.now + 300 * MS  # the VSC's timeout on CAN


def test_the_clients_next_deadline_is_the_timeout_of_the_one_heard_longest_ago() -> None:
    """SR-8.1, SR-2.4: with two required clients, the clients' next deadline is the timeout of
    the one heard longest ago, whichever said hello first, so that its loss is raised at its
    timeout and not at the other's."""
    clients = Clients((ClientSpec("arm", timeout_ms=500), ClientSpec("planner", timeout_ms=500)))
    for connection, name in ((1, "arm"), (2, "planner")):
        assert clients.connected(ClientConnected(0, connection, 1000)) is None
        assert clients.hello(ClientHello(0, connection, name)) is None
    assert clients.heartbeat(ClientHeartbeat(100 * MS, 2), 100 * MS) is None  # planner
    assert clients.heartbeat(ClientHeartbeat(300 * MS, 1), 300 * MS) is None  # arm

    core = SafetyCore(ROBOT, 0)  # the other machines, as a core composes them
    view = View(
        core._vsc, clients, RecordBudget(), core._outputs, core._battery, core._display, core._proof
    )

    def at(now: int) -> View:
        return view.at(now)

    assert clients.next_deadline(at(300 * MS)) == 600 * MS  # the planner's
    assert clients.next_deadline(at(600 * MS)) == 800 * MS  # then the arm's
