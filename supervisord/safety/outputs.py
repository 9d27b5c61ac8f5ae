"""The outputs as the safety core drives and checks them (SR-1, SR-1.4, SR-6).

Internal to the core, one of the machines :class:`~supervisord.safety.core.SafetyCore`
composes: :meth:`Outputs.levels` gives the levels after a step, :meth:`Outputs.readback` takes
a read-back in, :meth:`Outputs.faults` gives the ``output_fault`` conditions,
:meth:`Outputs.next_deadline` when a category-1 output goes off and :meth:`Outputs.canonical`
its canonical form (docs/verification.md).
"""

from __future__ import annotations

from types import MappingProxyType

from supervisord.safety.canonical import Clock, clock
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import OutputRole, SafetyConfig
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.safety.events import OutputReadback
from supervisord.safety.face import Seen
from supervisord.safety.transitions import State

Levels = MappingProxyType[str, bool]


class Outputs:
    """The configured outputs, a stop's category-1 delays and the read-backs that disagree."""

    def __init__(self, config: SafetyConfig) -> None:
        # Names and roles only, not the outputs' specifications: those are the edge's (a GPIO
        # chip, a file) and no snapshot of the core holds them (SR-7.13).
        self._roles = tuple((o.name, o.role) for o in config.outputs)
        self.names = frozenset(o.name for o in config.outputs)
        # Each category-1 output's delay (SR-1.4); the config is frozen: computed once.
        self._delays_ns = {o.name: o.off_delay_ns for o in config.outputs if o.off_delay_ms}
        self._delay_pairs = tuple(self._delays_ns.items())  # the same, hashable: the reflex's
        self._levels_by_state: dict[State, Levels] = {}
        # SR-1.4: when the motion outputs last went off (RUN left), and, in a stop begun with
        # power on while a category-1 output may still be on, that time again.
        self._motion_off_ns: int | None = None
        self._braking_since: int | None = None
        self._faults: dict[str, Details] = {}  # SR-6: read-backs that disagree, by output

    def levels(self, previous: State, state: State, now: int) -> Levels:
        """The outputs' levels after a step from ``previous`` to ``state``. SR-1.4: a stop
        begun while the power outputs were on (from HOLD or RUN) leaves each category-1 output
        on until its delay after the motion outputs went off, then off; a failure of the core
        itself (which forgets when motion went off: :meth:`category_0`) and a stop begun in
        STOPPED leave none on."""
        delays = self._delays_ns
        if not delays:
            return self.of(state)
        if previous is State.RUN and state is not State.RUN:
            self._motion_off_ns = now
        if state is not State.STOPPED:
            self._braking_since = None
        elif previous is not State.STOPPED:
            self._braking_since = self._motion_off_ns
        since = self._braking_since
        if since is None:
            return self.of(state)
        if now - since >= max(delays.values()):
            self._braking_since = None  # every delay is over: off for the rest of this stop
            return self.of(state)
        return MappingProxyType(
            {name: name in delays and now - since < delays[name] for name, _ in self._roles}
        )

    def reflex_facts(
        self,
    ) -> tuple[tuple[tuple[str, OutputRole], ...], tuple[tuple[str, int], ...], int | None]:
        """What the reflex is prepared from (SR-9.5, :mod:`~supervisord.safety.reflex`): the
        outputs' names and roles, the category-1 delays and when the motion outputs last went
        off, as hashable values."""
        return self._roles, self._delay_pairs, self._motion_off_ns

    def of(self, state: State) -> Levels:
        """SR-1: motion outputs on only in RUN; power outputs on in HOLD and RUN. Read-only
        and the same for every step in a state, so built once per state."""
        levels = self._levels_by_state.get(state)
        if levels is None:
            levels = self._levels_by_state[state] = MappingProxyType(
                {
                    name: state is State.RUN
                    if role is OutputRole.MOTION
                    else state is not State.STOPPED
                    for name, role in self._roles
                }
            )
        return levels

    def all_off(self) -> Levels:
        return MappingProxyType(dict.fromkeys(self.names, False))

    def category_0(self) -> None:
        """The core itself failed: a stop of category 0 (SR-1.4), no output stays on."""
        self._motion_off_ns = self._braking_since = None

    @property
    def braking(self) -> bool:
        """Whether a category-1 output may still be on in a stop: it goes off with time."""
        return self._braking_since is not None

    def readback(self, event: OutputReadback) -> Refusal | None:
        """A read-back of what an output was set to (SR-6); an output the config does not
        name is refused (``UNKNOWN_OUTPUT``: the daemon and the config disagree)."""
        if event.output not in self.names:
            return Refusal(RefusalReason.UNKNOWN_OUTPUT, event.output[:60], event)
        if event.read_back is None:
            self._faults[event.output] = make_details(
                [("requested", str(event.requested)), ("read_back", "failed")]
            )
        elif event.read_back != event.requested:
            self._faults[event.output] = make_details(
                [("requested", str(event.requested)), ("read_back", str(event.read_back))]
            )
        else:
            # SR-6: the condition clears when a later read-back matches what was set.
            self._faults.pop(event.output, None)
        return None

    def faults(self) -> dict[Cause, Details]:
        """``output_fault`` for each output whose last read-back disagreed (SR-6)."""
        return {Cause(CauseKind.OUTPUT_FAULT, n): d for n, d in self._faults.items()}

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """Only an output with a delay brakes (SR-1.4)."""
        return bool(self._delays_ns)

    def moving(self) -> bool:
        """A category-1 output braking goes off with time (SR-1.4)."""
        return self._braking_since is not None

    def due_by(self, view: Seen) -> bool:
        """While braking, its delays run: :meth:`moving` already declines (SR-1.4)."""
        return self._braking_since is not None

    def next_deadline(self, view: Seen) -> int | None:
        """The earliest time after ``view.now`` at which a category-1 output goes off (SR-1.4:
        at its delay, never later), or ``None``."""
        now = view.now
        earliest: int | None = None
        since = self._braking_since
        if since is not None:
            for delay in self._delays_ns.values():
                due = since + delay
                if now < due and (earliest is None or due < earliest):
                    earliest = due
        return earliest

    def canonical(self, view: Seen) -> tuple[tuple[object, ...], tuple[Clock, ...]]:
        """The facts and clocks of the outputs (docs/verification.md): the read-backs that
        disagree, and, only when an output has a delay, when motion went off and the stop's
        braking began."""
        now = view.now
        clocks: list[Clock] = []
        if self._delays_ns:  # SR-1.4: read only when an output has a delay
            delays = sorted(set(self._delays_ns.values()))
            for name, at in (("motion_off", self._motion_off_ns), ("braking", self._braking_since)):
                if at is not None:
                    clocks.append(clock(name, at, now, *delays))
        return (("output_faults", tuple(sorted(self._faults.items()))),), tuple(clocks)

    NOT_CANONICAL = frozenset({"_roles", "names", "_levels_by_state", "_delay_pairs"})
    """Attributes ``canonical`` leaves out: the config, and what is computed from it once."""
