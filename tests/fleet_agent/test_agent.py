"""The agent's decision for one message (SR-13.13, SR-13.14, SR-8.21): which topics it acts
on, what it sends the supervisor (only fleet ops), and what it refuses. The requests are
recorded by a requester that answers as the daemon's contract says (docs/api.md
"fleet_stop"); the real daemon answers in test_with_srcsd.py."""

from __future__ import annotations

import time
from typing import Any

from supervisord.fleet_agent.agent import Agent
from supervisord.fleet_agent.daemon_link import LinkFailed
from supervisord.fleet_agent.message import new_message
from supervisord.fleet_agent.replay import ReplayGuard

SENT: list[tuple[str, dict[str, str]]] = []


def _daemon(op: str, fields: dict[str, str]) -> dict[str, Any]:
    SENT.append((op, fields))
    if op == "fleet_stop":
        return {"ok": True, "op": op, "state": "STOPPED", "outputs": [], "record_seq": 3}
    return {"ok": True, "op": op}


def _agent() -> Agent:
    SENT.clear()
    return Agent("f1", "robot-a", frozenset({"site-1"}), _daemon, ReplayGuard())


def _handle(agent: Agent, topic: str, payload: bytes, *, retained: bool = False) -> Any:
    return agent.handle(topic, payload, retained=retained, arrived=time.monotonic())


def test_a_stop_for_its_group_is_passed_on_and_another_groups_ignored() -> None:
    agent = _agent()
    stop = new_message("stop", "s1", "console-1", time.time()).encode()
    assert _handle(agent, "srcs/f1/stop/group/site-2", stop) is None
    assert _handle(agent, "srcs/f1/stop/robot/robot-b", stop) is None
    assert _handle(agent, "srcs/f2/stop/all", stop) is None
    assert SENT == []
    answer = _handle(agent, "srcs/f1/stop/group/site-1", stop)
    assert answer.result == "stopped"
    assert SENT == [("fleet_stop", {"stop_id": "s1", "sender": "console-1"})]


def test_a_retained_stop_is_refused() -> None:
    agent = _agent()
    stop = new_message("stop", "s1", "console-1", time.time()).encode()
    answer = _handle(agent, "srcs/f1/stop/all", stop, retained=True)
    assert (answer.result, answer.reason) == ("refused", "retained")
    assert SENT == []


def test_a_keepalive_is_passed_on_only_fresh_from_its_topics_console() -> None:
    agent = _agent()
    now = time.time()
    fresh = new_message("keepalive", "keepalive", "console-1", now).encode()
    assert _handle(agent, "srcs/f1/keepalive/console-1", fresh) is None
    assert SENT == [("fleet_keepalive", {"sender": "console-1"})]
    assert agent.keepalive_error == ""
    # Sent again, held back 3 s, or under another console's name: not passed on.
    assert _handle(agent, "srcs/f1/keepalive/console-1", fresh) is None
    assert agent.keepalive_error == "keepalive refused: replayed"
    old = new_message("keepalive", "keepalive", "console-1", now - 3).encode()
    assert _handle(agent, "srcs/f1/keepalive/console-1", old) is None
    assert agent.keepalive_error == "keepalive refused: stale"
    assert _handle(agent, "srcs/f1/keepalive/console-2", fresh) is None
    assert agent.keepalive_error == "keepalive refused: not the topic's console"
    assert len(SENT) == 1


def test_a_keepalive_on_a_stop_topic_and_a_stop_on_a_keepalive_topic_are_refused() -> None:
    agent = _agent()
    keepalive = new_message("keepalive", "keepalive", "console-1", time.time()).encode()
    answer = _handle(agent, "srcs/f1/stop/all", keepalive)
    assert (answer.result, answer.reason) == ("refused", "kind")
    stop = new_message("stop", "s1", "console-1", time.time()).encode()
    assert _handle(agent, "srcs/f1/keepalive/console-1", stop) is None
    assert SENT == []


def test_a_supervisor_that_refuses_is_not_stopped_with_its_reason() -> None:
    def refusing(op: str, fields: dict[str, str]) -> dict[str, Any]:
        raise LinkFailed("supervisor refused: not_allowed")

    agent = Agent("f1", "robot-a", frozenset(), refusing, ReplayGuard())
    stop = new_message("stop", "s1", "console-1", time.time()).encode()
    answer = _handle(agent, "srcs/f1/stop/all", stop)
    assert (answer.result, answer.reason) == ("not_stopped", "supervisor refused: not_allowed")
