"""The console's count of one stop's answers (SR-13.15)."""

from __future__ import annotations

from supervisord.fleet_agent.ack import Ack
from supervisord.fleet_agent.tally import Round
from supervisord.fleet_agent.topics import ALL, Target


def _ack(robot: str, result: str = "stopped", stop_id: str = "s1", kind: str = "stop") -> Ack:
    return Ack(robot, stop_id, kind, result, "STOPPED" if result == "stopped" else None)


def test_all_is_every_known_robot_and_done_when_each_answered() -> None:
    tally = Round("s1", (ALL,))
    tally.presence("robot-a", frozenset({"site-1"}), online=True)
    tally.presence("robot-b", frozenset(), online=False)
    assert tally.expected == ["robot-a", "robot-b"]
    assert tally.answer(_ack("robot-a"), 0.01)
    assert [tally.done] == [False]  # a list: mypy would keep the property narrowed
    assert tally.silent == ["robot-b"]
    assert tally.answer(_ack("robot-b", "not_stopped"), 0.02)
    assert tally.done
    assert not tally.all_stopped


def test_a_group_is_its_members_and_named_robots_are_expected_unknown() -> None:
    tally = Round("s1", (Target("group", "site-1"),))
    tally.presence("robot-a", frozenset({"site-1"}), online=True)
    tally.presence("robot-c", frozenset({"site-2"}), online=True)
    assert tally.expected == ["robot-a"]
    named = Round("s1", (Target("robot", "robot-x"),))
    assert named.expected == ["robot-x"]
    assert named.silent == ["robot-x"]


def test_an_answer_to_another_stop_or_kind_is_not_counted() -> None:
    tally = Round("s1", (Target("robot", "robot-a"),), kind="release")
    assert not tally.answer(_ack("robot-a", stop_id="s0"), 0.0)
    # The stop's retained answer, while its release is waited for.
    assert not tally.answer(_ack("robot-a"), 0.0)
    assert tally.answer(_ack("robot-a", "released", kind="release"), 0.0)
    assert tally.done


def test_a_refused_copy_does_not_hide_the_robots_real_answer() -> None:
    tally = Round("s1", (Target("robot", "robot-a"),))
    assert tally.answer(_ack("robot-a", "refused"), 0.0)
    assert [tally.done] == [False]  # a list: mypy would keep the property narrowed
    assert tally.answer(_ack("robot-a"), 0.1)
    assert not tally.answer(_ack("robot-a", "refused"), 0.2)
    assert tally.all_stopped


def test_nobody_known_is_never_done() -> None:
    assert not Round("s1", (ALL,)).done
