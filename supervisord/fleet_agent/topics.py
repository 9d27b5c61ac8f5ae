"""The fleet's MQTT topics: who a stop is for, and where each robot answers (SR-13.13).

    srcs/<fleet>/stop/all               every robot
    srcs/<fleet>/stop/group/<group>     the robots of a group (a robot's groups: its agent's)
    srcs/<fleet>/stop/robot/<robot>     one robot
    srcs/<fleet>/ack/<robot>            that robot's acknowledgements (its agent alone writes)
    srcs/<fleet>/robot/<robot>          that robot's presence: its groups, online or not
    srcs/<fleet>/keepalive/<console>    a console's keepalive (for robots that require one)

Names are plain words (letters, digits, ``.``, ``_``, ``-``, 1 to 64): no ``/``, ``+`` or
``#``, so that a name can never widen a subscription or an ACL line into another robot's
topics. Pure: no MQTT client here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Final

PREFIX: Final = "srcs"
_NAME: Final = re.compile(r"[A-Za-z0-9._-]{1,64}")


def valid_name(name: str) -> bool:
    """A fleet's, robot's, group's or console's name fits in one topic level."""
    return _NAME.fullmatch(name) is not None and name not in (".", "..")


def checked_name(name: str, what: str) -> str:
    """``name``, or ``ValueError`` naming ``what`` it was meant to be."""
    if not valid_name(name):
        raise ValueError(f"{what} {name!r}: 1 to 64 letters, digits, '.', '_' or '-'")
    return name


@dataclass(frozen=True, slots=True)
class Target:
    """Who a stop is for: ``kind`` ``all`` (``name`` empty), ``group`` or ``robot``."""

    kind: str
    name: str = ""

    def covers(self, robot: str, groups: frozenset[str]) -> bool:
        """Whether a robot with these groups is one the stop is for."""
        if self.kind == "all":
            return True
        if self.kind == "group":
            return self.name in groups
        return self.kind == "robot" and self.name == robot


ALL: Final = Target("all")


def stop_topic(fleet: str, target: Target) -> str:
    """The topic a console publishes a stop for ``target`` to."""
    base = f"{PREFIX}/{fleet}/stop"
    return f"{base}/all" if target.kind == "all" else f"{base}/{target.kind}/{target.name}"


def stop_topics(fleet: str, robot: str, groups: frozenset[str]) -> list[str]:
    """Every topic a robot's agent subscribes to: its stops, and no other robot's, and the
    consoles' keepalives."""
    return [
        stop_topic(fleet, ALL),
        *(stop_topic(fleet, Target("group", g)) for g in sorted(groups)),
        stop_topic(fleet, Target("robot", robot)),
        keepalive_topic(fleet, "+"),
    ]


def keepalive_topic(fleet: str, console: str) -> str:
    """Where a console says it is there; every robot's agent reads every console's."""
    return f"{PREFIX}/{fleet}/keepalive/{console}"


def ack_topic(fleet: str, robot: str) -> str:
    return f"{PREFIX}/{fleet}/ack/{robot}"


def presence_topic(fleet: str, robot: str) -> str:
    return f"{PREFIX}/{fleet}/robot/{robot}"


def parse_stop_topic(fleet: str, topic: str) -> Target | None:
    """The target a stop topic names; ``None`` for any other topic (never raises)."""
    parts = topic.split("/")
    if len(parts) < 4 or parts[:3] != [PREFIX, fleet, "stop"]:
        return None
    rest = parts[3:]
    if rest == ["all"]:
        return ALL
    if len(rest) == 2 and rest[0] in ("group", "robot") and valid_name(rest[1]):
        return Target(rest[0], rest[1])
    return None


def parse_robot_topic(fleet: str, topic: str, kind: str) -> str | None:
    """The robot an ``ack`` or ``robot`` (presence) topic is of; ``None`` for another topic."""
    parts = topic.split("/")
    if len(parts) == 4 and parts[:3] == [PREFIX, fleet, kind] and valid_name(parts[3]):
        return parts[3]
    return None
