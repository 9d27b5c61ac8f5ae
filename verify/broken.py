"""Deliberately broken cores the exploration must reject (docs/verification.md "Faults the
checker must catch"; ``tests/safety/test_exploration.py`` runs them).

Each is one small patch of ``supervisord/safety/core.py``'s source, applied at test time to a
copy of the module loaded under another name: the product is never changed. A patch whose
text is no longer found in the source fails loudly, so a refactored core cannot silently
retire a fault.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from supervisord.safety import SafetyCore
from supervisord.safety import core as real_core


@dataclass(frozen=True)
class Fault:
    """A broken core: ``old`` replaced by ``new`` in core.py; the exploration of ``model``
    must find a violation of ``expected``."""

    name: str
    old: str
    new: str
    model: str
    expected: str


FAULTS = (
    Fault(
        "a dropped cause: a client's e-stop is forgotten",
        "{Cause(CauseKind.CLIENT_ESTOP, n): () for n in self._client_estops}",
        "{}",
        "clients",
        "P12",
    ),
    Fault(
        "a boundary off by one: the VSC's timeout expires 1 ns late",
        'lost = last is None or now - last >= self._vsc_timeout_ns  # ">=": 200 ms is lost',
        "lost = last is None or now - last > self._vsc_timeout_ns",
        "takeover",
        "P4",
    ),
    Fault(
        "a takeover without the dwell",
        "if span < TAKEOVER_DWELL_NS:  # rule 4: two heartbeats at least the dwell apart",
        "if False:",
        "takeover",
        "P2",
    ),
    Fault(
        "a missing record: a cause that clears is not recorded",
        "changes = self._book.take_changes()",
        "changes = tuple(c for c in self._book.take_changes() if c.kind is not ChangeKind.CLEARED)",
        "takeover",
        "P7",
    ),
    Fault(
        "a new stop waits for the next user heartbeat",
        "self._emit_link_frames(now, estop, urgent=raised_user_estop)",
        "self._emit_link_frames(now, estop, urgent=False)",
        "takeover",
        "P5",
    ),
    Fault(
        "the proof test is not waited for",
        "untested = proof.untested",
        "untested = False",
        "proof",
        "P6",
    ),
    Fault(
        "a required client not there keeps the proof test waiting",
        "calm = not self._book.user_estop(proof.quiet(stopped)) and",
        "calm = not self._book.user_estop() and",
        "proof_clients",
        "P20",
    ),
    Fault(
        "a missing required client's byte stays 0 after the proof test",
        "quiet = self._proof.quiet(self._state is State.STOPPED)",
        "quiet = frozenset({CauseKind.CLIENT_LOST})",
        "proof_clients",
        "P5",
    ),
    Fault(
        "the deadline forgets the VSC's timeout",
        "if last is not None and now < (due := last + self._vsc_timeout_ns) < earliest:",
        "if False:",
        "can",
        "P8",
    ),
    Fault(
        "a mode's hold is ignored",
        "mode = self._held_mode\n",
        "mode = None\n",
        "takeover",
        "P9",
    ),
    Fault(
        "a re-arm while a client commands motion",
        "        if self._nonzero:\n            # SR-4.6",
        "        if False:\n            # SR-4.6",
        "clients",
        "P18",
    ),
    Fault(
        "the remote's battery report never goes stale before another input",
        "if stale is not None and now < stale < earliest:  # SR-8.12: the report is too old",
        "if False:  # SR-8.12: the report is too old",
        "battery_stop",
        "P8",
    ),
    Fault(
        "a low battery is read as a good one",
        "            now,\n            level,\n            seen,\n",
        "            now,\n            100,\n            seen,\n",
        "battery_stop",
        "P19",
    ),
    Fault(
        "the battery's hold ends at the first good report",
        "            elif now - first >= BATTERY_SETTLE_NS:",
        "            elif now - first >= 0:",
        "battery_hold",
        "P19",
    ),
    Fault(
        "the battery's cause follows every report's reason",
        "                    and now - self._battery_words_since >= BATTERY_SETTLE_NS",
        "                    and now - self._battery_words_since >= 0",
        "battery_stop",
        "P21",
    ),
    Fault(
        "the re-arm hold is not waited for",
        "if clear_since is None or now - clear_since < hold:",
        "if clear_since is None:",
        "takeover",
        "P2",
    ),
    Fault(
        "a heartbeat counts whatever its progress",
        "stale = self._progress.beat(name, event.progress)",
        "stale = None",
        "progress",
        "P22",
    ),
    Fault(
        "a refused heartbeat still extends the deadline",
        "        if stale is None:\n            self._client_beat_ns[name] = now\n        else:",
        "        self._client_beat_ns[name] = now\n        if stale is not None:",
        "progress",
        "P8",
    ),
)


def broken_core(fault: Fault) -> type[SafetyCore]:
    """The ``SafetyCore`` of a copy of core.py with ``fault`` applied."""
    source = Path(real_core.__file__).read_text(encoding="utf-8")
    if source.count(fault.old) != 1:
        raise ValueError(f"{fault.name}: the patched text is not in core.py exactly once")
    name = f"verify._broken_{FAULTS.index(fault)}"
    module = _load(name, source.replace(fault.old, fault.new), real_core.__file__)
    core_class: type[SafetyCore] = module.SafetyCore
    return core_class


def _load(name: str, source: str, path: str) -> ModuleType:
    spec = importlib.util.spec_from_loader(name, loader=None, origin=path)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is built
    exec(compile(source, path, "exec"), module.__dict__)  # noqa: S102 -- our own source, patched
    return module
