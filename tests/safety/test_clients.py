"""Clients on the local socket (SR-8): names, requests and nonsense inputs."""

from __future__ import annotations

from supervisord.safety import ClientHello, RefusalReason, Request, State
from tests.safety.rig import OPERATIONAL, Rig


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
