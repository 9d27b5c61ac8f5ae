"""The fleet's topics: a robot subscribes to its stops and no other robot's (SR-13.13)."""

from __future__ import annotations

import pytest

from supervisord.fleet_agent.topics import (
    ALL,
    Target,
    ack_topic,
    parse_robot_topic,
    parse_stop_topic,
    stop_topic,
    stop_topics,
    valid_name,
)


def test_a_robot_subscribes_to_all_its_groups_and_itself() -> None:
    assert stop_topics("f1", "robot-a", frozenset({"site-2", "site-1"})) == [
        "srcs/f1/stop/all",
        "srcs/f1/stop/group/site-1",
        "srcs/f1/stop/group/site-2",
        "srcs/f1/stop/robot/robot-a",
        "srcs/f1/keepalive/+",
    ]


@pytest.mark.parametrize("target", [ALL, Target("group", "site-1"), Target("robot", "robot-b")])
def test_a_stop_topic_reads_back_as_its_target(target: Target) -> None:
    assert parse_stop_topic("f1", stop_topic("f1", target)) == target


@pytest.mark.parametrize(
    "topic",
    [
        "srcs/f2/stop/all",  # another fleet
        "srcs/f1/stop/robot",
        "srcs/f1/stop/robot/a/b",
        "srcs/f1/stop/group/+",
        "srcs/f1/stop/group/#",
        "srcs/f1/stop/everyone/x",
        "srcs/f1/ack/robot-a",
        "",
        "////",
    ],
)
def test_any_other_topic_is_no_stop(topic: str) -> None:
    assert parse_stop_topic("f1", topic) is None


def test_who_a_target_covers() -> None:
    groups = frozenset({"site-1"})
    assert ALL.covers("robot-a", groups)
    assert Target("group", "site-1").covers("robot-a", groups)
    assert not Target("group", "site-2").covers("robot-a", groups)
    assert Target("robot", "robot-a").covers("robot-a", groups)
    assert not Target("robot", "robot-b").covers("robot-a", groups)


@pytest.mark.parametrize("name", ["+", "#", "a/b", "", "..", "x" * 65, "é", "a b"])
def test_a_name_that_could_widen_a_topic_is_refused(name: str) -> None:
    assert not valid_name(name)


def test_ack_topics_read_back_as_their_robot() -> None:
    assert parse_robot_topic("f1", ack_topic("f1", "robot-a"), "ack") == "robot-a"
    assert parse_robot_topic("f1", "srcs/f1/ack/+", "ack") is None
    assert parse_robot_topic("f1", "srcs/f1/robot/robot-a", "ack") is None
