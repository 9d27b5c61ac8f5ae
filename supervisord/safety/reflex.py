"""The reflex: what a stopping VSC heartbeat switches off at once, known before the full step
(SR-9.5; docs/performance.md "The reflex").

A stop's time to off is mostly the core's full step, run cold (docs/performance.md). Yet what
a VSC heartbeat switches off *at once* depends on little: the state the core is in, and of the
heartbeat only whether its mode leaves Operational (a hold, SR-3.1) and whether its e-stop word
is set (a stop, SR-2.1). A :class:`Reflex` is that answer as plain data: a table keyed by those
two bits, each entry the outputs to switch off. The daemon looks it up for a heartbeat whose
mode or word differ from the last, writes those outputs off, and then runs the full step as
always, which decides everything else (its records, frames, causes) and the outputs again.

Exactly what the full step switches off at once, nothing more, nothing less (the exhaustive
exploration's P23 checks it in every state and for every heartbeat it explores):

- in RUN, a mode that is not Operational is HOLD: every motion output off (SR-1.2);
- in RUN, an e-stop word is STOPPED: every output off but a category-1 output, which stays on
  through its delay after the motion outputs went off, here and now (SR-1.4);
- in HOLD, an e-stop word is STOPPED: every power output off but a category-1 output whose
  delay since the motion outputs went off (when RUN was last left) has not passed; the entry
  keeps, per output, the time from which it goes off at once (:data:`ALWAYS`: at any time);
- in STOPPED, nothing (every output is off, or a category-1 output goes off with time, never
  with a heartbeat).

The reflex only ever switches outputs off. It holds for a heartbeat that arrives before the
core's ``next_deadline``, or when only the user heartbeat is due then: at any other time, time
passing (a timeout) decides too, the core gives no reflex and the loop leaves that heartbeat
to the full step. It is derived from the state and no part of it: not in the
canonical form, not in the snapshot.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Final

from supervisord.protocol.codes import VscMode
from supervisord.safety.config import OutputRole
from supervisord.safety.transitions import State

ALWAYS: Final = -(1 << 62)
"""An entry's time for an output that goes off at once whenever the heartbeat arrives."""
OPERATIONAL: Final = int(VscMode.OPERATIONAL)

Key = tuple[bool, bool]
"""What the heartbeat says: (its mode is not Operational, its e-stop word is not 0)."""
Entry = tuple[tuple[str, int], ...]
"""Outputs to switch off, each with the time from which it goes off at once."""

HOLD_KEY: Final[Key] = (True, False)
STOP_KEYS: Final[tuple[Key, Key]] = ((False, True), (True, True))


@dataclass(frozen=True, slots=True)
class Reflex:
    """What a heartbeat switches off at once from one state of the core: ``table`` by
    :data:`Key`; a key it does not hold switches nothing off."""

    table: Mapping[Key, Entry]

    def off(self, mode: int, estop: int, now: int) -> tuple[str, ...]:
        """The outputs a VSC heartbeat with ``mode`` and ``estop``, read at ``now`` (when time
        decides nothing else, ``SafetyCore.reflex``), switches off at once."""
        entry = self.table.get((mode != OPERATIONAL, estop != 0))
        if entry is None:
            return ()
        return tuple(name for name, since in entry if now >= since)


NOTHING: Final = Reflex(MappingProxyType({}))


@functools.lru_cache(maxsize=16)
def prepare(
    state: State,
    roles: tuple[tuple[str, OutputRole], ...],
    delays_ns: tuple[tuple[str, int], ...],
    motion_off_ns: int | None,
) -> Reflex:
    """The reflex of a core in ``state`` with outputs ``roles`` (in the config's order),
    category-1 delays ``delays_ns`` (SR-1.4) and the motion outputs last gone off at
    ``motion_off_ns`` (``None``: not since the start, or no output has a delay). A pure
    function of hashable values, so kept for the states seen last (a stop's lookup finds it
    made)."""
    if state is State.STOPPED:
        return NOTHING
    delays = dict(delays_ns)
    table: dict[Key, Entry] = {}
    if state is State.RUN:
        # SR-1.2: HOLD keeps the power outputs on. SR-1.4: a stop from RUN starts a
        # category-1 output's delay now, so it stays on.
        held = tuple((name, ALWAYS) for name, role in roles if role is OutputRole.MOTION)
        stopped = tuple((name, ALWAYS) for name, _ in roles if name not in delays)
        if held:
            table[HOLD_KEY] = held
    else:  # HOLD: the motion outputs are off already; a stop takes the power outputs
        stopped = tuple(
            (name, _off_from(delays.get(name), motion_off_ns))
            for name, role in roles
            if role is OutputRole.POWER
        )
    if stopped:
        for key in STOP_KEYS:
            table[key] = stopped
    return Reflex(MappingProxyType(table))


def _off_from(delay_ns: int | None, motion_off_ns: int | None) -> int:
    """SR-1.4: a category-1 output stays on until its delay after the motion outputs went off;
    without a delay, or without a time they went off, it goes off at once."""
    if delay_ns is None or motion_off_ns is None:
        return ALWAYS
    return motion_off_ns + delay_ns
