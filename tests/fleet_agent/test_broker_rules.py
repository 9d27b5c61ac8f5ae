"""The broker's rules, in a real mosquitto with the fleet's mutual TLS and ACL file
(SR-13.13): a robot reads only its stops and writes only its own answers, only a console
sends a stop, and a certificate of another CA is refused."""

from __future__ import annotations

import queue
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.fleet_agent.acl import acl_text
from supervisord.fleet_agent.mqtt_edge import Connection, Incoming, Tls
from tests.fleet_agent.broker import FLEET, Broker, pki, running_broker, tls

SETTLE_S = 1.5
"""How long a message that should not arrive is waited for: the broker forwards one that is
allowed within milliseconds (each test first sees an allowed one arrive)."""


@pytest.fixture(scope="module")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    with running_broker(tmp_path_factory.mktemp("broker")) as running:
        yield running


def _client(broker: Broker, name: str, topics: list[str]) -> Connection:
    connection = Connection(f"test-{name}-{time.monotonic_ns()}", tls(broker.pki, name), topics)
    connection.start("127.0.0.1", broker.port)
    deadline = time.monotonic() + 20
    while not connection.subscribed.is_set():
        assert time.monotonic() < deadline, connection.last_error
        time.sleep(0.02)
    return connection


def _topics(received: queue.Queue[Incoming], wait: float) -> list[str]:
    found = []
    deadline = time.monotonic() + wait
    while (left := deadline - time.monotonic()) > 0:
        try:
            found.append(received.get(timeout=left).topic)
        except queue.Empty:
            break
    return found


def test_a_robot_reads_its_stops_and_not_another_robots(broker: Broker) -> None:
    a = _client(broker, "robot-a", [f"srcs/{FLEET}/stop/robot/robot-a"])
    # robot-c asks for robot-a's stops and a wildcard: the ACL gives it neither.
    c = _client(broker, "robot-c", [f"srcs/{FLEET}/stop/robot/robot-a", f"srcs/{FLEET}/stop/#"])
    console = _client(broker, "console-1", [])
    try:
        assert console.publish(f"srcs/{FLEET}/stop/robot/robot-a", b"x")
        assert _topics(a.incoming, 10)[:1] == [f"srcs/{FLEET}/stop/robot/robot-a"]
        assert _topics(c.incoming, SETTLE_S) == []
    finally:
        for each in (a, c, console):
            each.stop()


def test_a_robot_cannot_send_a_stop_nor_answer_for_another_robot(broker: Broker) -> None:
    b = _client(broker, "robot-b", [f"srcs/{FLEET}/stop/all", f"srcs/{FLEET}/stop/group/site-1"])
    console = _client(broker, "console-1", [f"srcs/{FLEET}/ack/+"])
    a = _client(broker, "robot-a", [])
    try:
        a.publish(f"srcs/{FLEET}/stop/all", b"forged")
        a.publish(f"srcs/{FLEET}/stop/group/site-1", b"forged")
        a.publish(f"srcs/{FLEET}/ack/robot-b", b"forged")
        a.publish(f"srcs/{FLEET}/ack/robot-a", b"own")
        # Its own answer arrives; the forged ones never do.
        assert _topics(console.incoming, 10)[:1] == [f"srcs/{FLEET}/ack/robot-a"]
        assert _topics(console.incoming, SETTLE_S) == []
        assert _topics(b.incoming, SETTLE_S) == []
        # A console's stop to all does arrive.
        console.publish(f"srcs/{FLEET}/stop/all", b"real")
        assert _topics(b.incoming, 10)[:1] == [f"srcs/{FLEET}/stop/all"]
    finally:
        for each in (a, b, console):
            each.stop()


def test_a_certificate_the_broker_does_not_know_is_refused(broker: Broker, tmp_path: Path) -> None:
    other = pki(tmp_path / "other", ["robot-a"])
    forged = tls(other, "robot-a")
    # It trusts the broker (the fleet's CA) and shows robot-a's name signed by another CA.
    shown = Tls(broker.pki / "ca.pem", forged.certfile, forged.keyfile)
    connection = Connection("forged", shown, [f"srcs/{FLEET}/stop/all"])
    connection.start("127.0.0.1", broker.port)
    try:
        time.sleep(2.0)  # a connection would take milliseconds
        assert not connection.subscribed.is_set()
        assert not connection.connected
    finally:
        connection.stop()


def test_a_name_that_is_a_robot_and_a_console_is_refused() -> None:
    with pytest.raises(ValueError, match="robot-a"):
        acl_text(FLEET, {"robot-a": frozenset()}, ["robot-a"])
    with pytest.raises(ValueError, match="robot"):
        acl_text(FLEET, {"a/#": frozenset()}, [])


def test_the_acl_lines_of_a_robot() -> None:
    text = acl_text(FLEET, {"robot-a": frozenset({"site-1"})}, ["console-1"])
    assert (
        "user robot-a\ntopic read srcs/f1/stop/all\ntopic read srcs/f1/stop/group/site-1\n" in text
    )
    assert "topic write srcs/f1/ack/robot-a\n" in text
    assert "user console-1\ntopic write srcs/f1/stop/#\n" in text
