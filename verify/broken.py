"""Deliberately broken cores the exploration must reject (docs/verification.md "Faults the
checker must catch"; ``tests/safety/test_exploration.py`` runs them).

Each is one small patch of the source of one module of the core (``core.py`` or one of the
machines it composes), applied at test time to a copy of the module loaded under another name,
with a copy of ``core.py`` that composes the patched machine: the product is never changed. A
patch whose text is no longer found in the source fails loudly, so a refactored core cannot
silently retire a fault.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from supervisord.safety import SafetyCore
from supervisord.safety import cheap as real_cheap
from supervisord.safety import core as real_core


@dataclass(frozen=True)
class Fault:
    """A broken core: ``old`` replaced by ``new`` in ``module`` (of ``supervisord.safety``);
    the exploration of ``model`` must find a violation of ``expected``."""

    name: str
    old: str
    new: str
    model: str
    expected: str
    module: str = "core"


FAULTS = (
    Fault(
        "a dropped cause: a client's e-stop is forgotten",
        "return {Cause(CauseKind.CLIENT_ESTOP, n): () for n in self._estops}",
        "return {}",
        "clients",
        "P12",
        module="clients",
    ),
    Fault(
        "a boundary off by one: the VSC's timeout expires 1 ns late",
        'return last is None or now - last >= self._timeout_ns  # ">=": 200 ms is lost',
        "return last is None or now - last > self._timeout_ns",
        "takeover",
        "P4",
        module="vsc",
    ),
    Fault(
        "a takeover without the dwell",
        "if span < TAKEOVER_DWELL_NS:  # rule 4: two heartbeats at least the dwell apart",
        "if False:",
        "takeover",
        "P2",
        module="vsc",
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
        "            urgent=raised_user_estop,\n",
        "            urgent=False,\n",
        "takeover",
        "P5",
    ),
    Fault(
        "the proof test is not waited for",
        "untested = proof.untested",
        "untested = False",
        "proof",
        "P6",
        module="conditions",
    ),
    Fault(
        "a required client not there keeps the proof test waiting",
        "calm = not book.user_estop(proof.quiet(stopped)) and",
        "calm = not book.user_estop() and",
        "proof_clients",
        "P20",
        module="conditions",
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
        "candidates = [None if last is None else last + self._timeout_ns]  # SR-2.2",
        "candidates: list[int | None] = [None]",
        "can",
        "P8",
        module="vsc",
    ),
    Fault(
        "a mode's hold is ignored",
        "mode = self._held_mode\n",
        "mode = None\n",
        "takeover",
        "P9",
        module="vsc",
    ),
    Fault(
        "a re-arm while a client commands motion",
        "    if commanding:\n        # SR-4.6",
        "    if False:\n        # SR-4.6",
        "clients",
        "P18",
        module="rearm",
    ),
    Fault(
        "the remote's battery report never goes stale before another input",
        "return stale if stale is not None and stale > view.now else None",
        "return None",
        "battery_stop",
        "P8",
        module="battery",
    ),
    Fault(
        "a low battery is read as a good one",
        "            now,\n            level,\n            seen,\n",
        "            now,\n            100,\n            seen,\n",
        "battery_stop",
        "P19",
        module="battery",
    ),
    Fault(
        "the battery's hold ends at the first good report",
        "            elif now - first >= BATTERY_SETTLE_NS:",
        "            elif now - first >= 0:",
        "battery_hold",
        "P19",
        module="battery",
    ),
    Fault(
        "the battery's cause follows every report's reason",
        "and taken_in and now - self._words_since >= BATTERY_SETTLE_NS)",
        "and taken_in and now - self._words_since >= 0)",
        "battery_stop",
        "P21",
        module="battery",
    ),
    Fault(
        "the re-arm hold is not waited for",
        "if clear_since is None or now - clear_since < hold:",
        "if clear_since is None:",
        "takeover",
        "P2",
        module="rearm",
    ),
    Fault(
        "the reflex omits an output: an e-stop in RUN leaves the power output to the full step",
        "stopped = tuple((name, ALWAYS) for name, _ in roles if name not in delays)",
        "stopped = tuple((name, ALWAYS) for name, r in roles if r is OutputRole.MOTION)",
        "can",
        "P23",
        module="reflex",
    ),
    Fault(
        "the reflex cuts a category-1 output early: a stop from HOLD ignores the delay",
        "    if delay_ns is None or motion_off_ns is None:\n        return ALWAYS",
        "    if True:\n        return ALWAYS",
        "category1",
        "P23",
        module="reflex",
    ),
    Fault(
        "a heartbeat counts whatever its progress",
        "stale = self._progress.beat(name, event.progress)",
        "stale = None",
        "progress",
        "P22",
        module="clients",
    ),
    Fault(
        "a refused heartbeat still extends the deadline",
        "        if stale is None:\n"
        "            self._beat_ns[name] = now\n"
        "            return None\n",
        "        self._beat_ns[name] = now\n        if stale is None:\n            return None\n",
        "progress",
        "P8",
        module="clients",
    ),
    Fault(
        "a fleet release re-arms: a message from the network asks a local reset",
        "        step.refuse_if(self._clients.fleet.release(event))\n",
        "        step.refuse_if(self._clients.fleet.release(event))\n"
        "        return RearmRequest(RearmKind.LOCAL_RESET, Caller(0, 0, 'fleet', admin=True))\n",
        "fleet",
        "P2",  # P24 too, in the same step (tests/safety/test_exploration.py): P2 is checked first
    ),
    Fault(
        "the required console's loss is never raised",
        "lost = clients.fleet.console_lost(now)  # SR-8.21",
        "lost = None",
        "fleet",
        "P25",
        module="conditions",
    ),
)

CHEAP_FAULT = Fault(
    "the cheap path ignores one machine: the VSC's timeout at the user heartbeat",
    "for machine in view.machines:  # noqa: SIM110",
    "for machine in view.machines[1:]:  # noqa: SIM110",
    "vsc",
    "P17",
    module="cheap",
)
"""A cheap path that decides otherwise than the full step: P17 must see it (besides the
properties of what it then gets wrong, P4 and P23, which see it first)."""


def broken_core(fault: Fault) -> type[SafetyCore]:
    """The ``SafetyCore`` of a copy of core.py with ``fault`` applied (to core.py or to the
    machine it composes, whose patched copy the copy of core.py imports)."""
    real = importlib.import_module(f"supervisord.safety.{fault.module}")
    assert real.__file__ is not None
    source = Path(real.__file__).read_text(encoding="utf-8")
    if source.count(fault.old) != 1:
        raise ValueError(f"{fault.name}: the patched text is not in {fault.module}.py exactly once")
    name = f"verify._broken_{FAULTS.index(fault) if fault in FAULTS else len(FAULTS)}"
    patched = _load(name, source.replace(fault.old, fault.new), real.__file__)
    if real is real_core:
        core_class: type[SafetyCore] = patched.SafetyCore
        return core_class
    # The modules that compose the patched one again, each ``from supervisord.safety.MODULE
    # import ...`` reading the patched copy: the cheap path (it ends with the next deadline)
    # unless it is the one patched, then core.py.
    names = [real.__name__, real_cheap.__name__]
    originals = {n: sys.modules[n] for n in names}
    try:
        sys.modules[real.__name__] = patched
        if real is not real_cheap:
            sys.modules[real_cheap.__name__] = _load(
                f"{name}_cheap", _source(real_cheap), str(real_cheap.__file__)
            )
        module = _load(f"{name}_core", _source(real_core), str(real_core.__file__))
    finally:
        sys.modules.update(originals)
    composed: type[SafetyCore] = module.SafetyCore
    return composed


def _source(module: ModuleType) -> str:
    assert module.__file__ is not None
    return Path(module.__file__).read_text(encoding="utf-8")


def _load(name: str, source: str, path: str) -> ModuleType:
    spec = importlib.util.spec_from_loader(name, loader=None, origin=path)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is built
    exec(compile(source, path, "exec"), module.__dict__)  # noqa: S102 -- our own source, patched
    return module
