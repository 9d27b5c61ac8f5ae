"""The console and the agents through a real broker, without a supervisor that answers
(SR-13.14, SR-13.15): a robot whose supervisor is down answers not stopped with the reason, a
robot without an agent is silent, an agent refuses a stop sent again, and every line says
which. The acknowledged stop from a real srcsd: tests/fleet_agent/test_with_srcsd.py."""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Iterator

import pytest

from supervisord.fleet_agent.message import new_message
from tests.fleet_agent.agents import console, running_agents, watcher
from tests.fleet_agent.broker import FLEET, Broker, running_broker


@pytest.fixture(scope="module")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    with running_broker(tmp_path_factory.mktemp("broker")) as running:
        yield running


@pytest.fixture(scope="module")
def agents(broker: Broker, tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """robot-a and robot-b, whose supervisors' sockets do not exist; robot-c has no agent."""
    where = tmp_path_factory.mktemp("agents")
    sockets = {r: where / f"{r}.sock" for r in ("robot-a", "robot-b")}
    with running_agents(broker, sockets, where):
        yield


def test_a_robot_whose_supervisor_is_down_answers_not_stopped_with_why(
    broker: Broker, agents: None, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = console(broker, capsys, "stop", "robot-a", "--deadline", "10")
    assert status == 1
    assert "robot-a" in out
    assert "not stopped: supervisor unreachable" in out
    assert "every robot answered (1)" in out


def test_a_robot_without_an_agent_is_named_silent_at_the_deadline(
    broker: Broker, agents: None, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = console(broker, capsys, "stop", "robot-a", "robot-c", "--deadline", "3")
    assert status == 1
    lines = out.splitlines()
    assert any(line.startswith("robot-c") and "silent: no answer" in line for line in lines)
    assert any(line.startswith("robot-a") and "not stopped" in line for line in lines)
    assert "1 of 2 answered" in out
    assert "silent: robot-c" in out


def test_a_group_is_its_known_robots(
    broker: Broker, agents: None, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = console(broker, capsys, "stop", "--group", "site-1", "--deadline", "10", "--json")
    rows = [json.loads(line) for line in out.splitlines()]
    assert {r["robot"] for r in rows if "robot" in r} == {"robot-a", "robot-b"}
    assert rows[-1]["all_answered"] is True
    assert status == 1  # answered, not stopped: no supervisor


def test_a_stop_sent_again_is_refused_as_replayed(broker: Broker, agents: None) -> None:
    acks = watcher(broker, [f"srcs/{FLEET}/ack/robot-b"])
    sender = watcher(broker, [])
    try:
        message = new_message("stop", "replay-1", "console-1", time.time()).encode()
        for _ in range(2):  # the console's send, then the attacker's copy of the same bytes
            sender.publish(f"srcs/{FLEET}/stop/robot/robot-b", message)
        answers: list[tuple[str, str]] = []
        deadline = time.monotonic() + 20
        while len(answers) < 2 and time.monotonic() < deadline:
            try:
                item = acks.incoming.get(timeout=1)
            except queue.Empty:
                continue
            answer = json.loads(item.payload)
            if answer["stop_id"] == "replay-1":
                answers.append((answer["result"], answer["reason"]))
        assert answers[0] == ("not_stopped", answers[0][1])  # forwarded (no supervisor)
        assert answers[1] == ("refused", "replayed")
    finally:
        acks.stop()
        sender.stop()


def test_a_stale_stop_is_refused(broker: Broker, agents: None) -> None:
    acks = watcher(broker, [f"srcs/{FLEET}/ack/robot-b"])
    sender = watcher(broker, [])
    try:
        old = new_message("stop", "old-1", "console-1", time.time() - 120).encode()
        sender.publish(f"srcs/{FLEET}/stop/robot/robot-b", old)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                answer = json.loads(acks.incoming.get(timeout=1).payload)
            except queue.Empty:
                continue
            if answer["stop_id"] == "old-1":
                assert (answer["result"], answer["reason"]) == ("refused", "stale")
                return
        raise AssertionError("no answer to the stale stop")
    finally:
        acks.stop()
        sender.stop()


def test_status_names_the_known_robots(
    broker: Broker, agents: None, capsys: pytest.CaptureFixture[str]
) -> None:
    status, out = console(broker, capsys, "status", "--wait", "2")
    assert status == 0
    line = next(line for line in out.splitlines() if line.startswith("robot-a"))
    assert "online" in line
    assert "site-1" in line
