"""A fleet stop's acknowledgement, built after the stop is applied (SR-8.20; docs/api.md
"fleet_stop").

The reply says what happened, not what was asked: the state after the stop, every output's
level and what it read back when written off again (``offcheck.py``), the sequence number of
the record that raised the stop, and the monotonic time from the request's arrival to the last
read-back. A repeat of a stop id the core took already (the agent sends again when a reply was
lost) changes nothing in the core and gets the first acknowledgement again, marked ``repeat``,
with the new request's ``id``: the console counts a robot once, with the facts of its stop.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from collections.abc import Callable

from supervisord.api.replies import FleetOutput, FleetStopReply
from supervisord.api.requests import FleetStopRequest
from supervisord.daemon.loop import Snapshot
from supervisord.safety.decision import Decision
from supervisord.safety.events import FleetStop
from supervisord.safety.fleet import SEEN_MAX
from supervisord.timebase import NS_PER_MS


class FleetAcks:
    """The acknowledgements of the last ``SEEN_MAX`` stop ids (the core keeps as many ids:
    a repeat it ignores is one whose acknowledgement is here). ``last``: the listener's last
    applied decision, the state after the stop and the read-backs it caused."""

    def __init__(self, last: Callable[[], Decision | None]) -> None:
        self._last = last
        self._acks: OrderedDict[str, FleetStopReply] = OrderedDict()

    def acknowledge(
        self, request: FleetStopRequest, decision: Decision, now: int, snapshot: Snapshot
    ) -> FleetStopReply:
        """The reply to ``request``, read at ``now``, which the core decided as ``decision``
        (and the loop applied)."""
        first = self._acks.get(request.stop_id)
        if first is not None:
            return dataclasses.replace(first, id=request.id, repeat=True)
        check = snapshot.check_off() if snapshot.check_off is not None else None
        outputs = (
            tuple(
                FleetOutput(name=o.name, level=o.level, readback=o.readback) for o in check.outputs
            )
            if check is not None
            else tuple(
                FleetOutput(name=name, level=on, readback=None)
                for name, on in decision.outputs.items()
            )
        )
        sequence = next(
            (r.sequence for r in decision.records if isinstance(r.trigger, FleetStop)), None
        )
        offset = check.sequence_offset if check is not None else 0
        checked = check.checked_ns if check is not None else now
        last = self._last() or decision
        ack = FleetStopReply(
            id=request.id,
            stop_id=request.stop_id,
            state=last.state,
            outputs=outputs,
            record_seq=None if sequence is None else offset + sequence,
            arrival_to_off_ms=max(0, checked - now) / NS_PER_MS,
        )
        self._acks[request.stop_id] = ack
        while len(self._acks) > SEEN_MAX:
            self._acks.popitem(last=False)
        return ack
