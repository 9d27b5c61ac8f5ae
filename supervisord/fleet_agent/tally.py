"""The console's count of one stop's answers (SR-13.15): who it was for, who answered what,
who is silent, and whether every robot has answered. Pure: the console feeds it the
presence messages and acknowledgements the broker delivers, and asks it at the deadline.

Who a stop is for: the robots named (``srcsctl fleet stop ROBOT...``), or for ``--all`` and
``--group`` every robot the broker knows by its presence message (retained at the broker, so
a robot that was ever there is known, an agent that went away marked offline by its will) and
covered by the target. A robot that answers without a presence message counts too.
An acknowledgement of another stop (a robot's retained answer to an earlier one), or of the
same stop's other kind (the stop's answer, when its release is sent), is not this one's. A
robot's first conclusive answer (``stopped``, ``not_stopped``, ``released``) is kept: a later
``refused`` for the same stop (a duplicate the agent refused as ``replayed``) does not hide it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from supervisord.fleet_agent.ack import Ack
from supervisord.fleet_agent.topics import Target

CONCLUSIVE = frozenset({"stopped", "not_stopped", "released"})


@dataclass
class Presence:
    groups: frozenset[str]
    online: bool


@dataclass
class Round:
    stop_id: str | None
    targets: tuple[Target, ...]
    kind: str = "stop"
    roster: dict[str, Presence] = field(default_factory=dict)
    answers: dict[str, Ack] = field(default_factory=dict)
    answered_at: dict[str, float] = field(default_factory=dict)

    def presence(self, robot: str, groups: frozenset[str], online: bool) -> None:
        self.roster[robot] = Presence(groups, online)

    def answer(self, ack: Ack, at: float) -> bool:
        """Count ``ack`` (``at``: when it arrived); ``False`` when it is not this stop's or a
        robot's answer is already conclusive."""
        if self.stop_id is not None and (ack.stop_id, ack.kind) != (self.stop_id, self.kind):
            return False
        held = self.answers.get(ack.robot)
        if held is not None and (held.result in CONCLUSIVE or ack.result not in CONCLUSIVE):
            return False
        self.answers[ack.robot] = ack
        self.answered_at[ack.robot] = at
        return True

    def _covered(self, robot: str) -> bool:
        groups = self.roster[robot].groups if robot in self.roster else frozenset()
        return any(t.covers(robot, groups) for t in self.targets)

    @property
    def expected(self) -> list[str]:
        named = {t.name for t in self.targets if t.kind == "robot"}
        known = {r for r in self.roster if self._covered(r)}
        return sorted(named | known | set(self.answers))

    @property
    def silent(self) -> list[str]:
        return [r for r in self.expected if r not in self.answers]

    @property
    def done(self) -> bool:
        """Every robot the stop is for has answered conclusively (and there is one)."""
        expected = self.expected
        return bool(expected) and all(
            r in self.answers and self.answers[r].result in CONCLUSIVE for r in expected
        )

    @property
    def all_stopped(self) -> bool:
        return self.done and all(self.answers[r].result == "stopped" for r in self.expected)
