"""The safety core's snapshot and its restore (SR-7.11; ``supervisord/safety/snapshot.py``,
docs/record.md "Where a window starts"): a core restored from the JSON text of a snapshot, at
any point of any input sequence, makes the same decisions as the core it was taken from; and a
snapshot that is damaged or not of this code is refused, never half restored."""

from __future__ import annotations

import copy
import dataclasses
import json
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import event as note
from hypothesis import strategies as st

from supervisord.outputs.gpio import GpioSpec
from supervisord.protocol.messages import FeedbackSet, VscHeartbeat
from supervisord.safety import SafetyConfig, SafetyCore
from supervisord.safety.config import OutputRole
from supervisord.safety.events import ClientConnected, LinkOpened, VscReceived
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.safety.snapshot import SnapshotError, restore, snapshot
from tests.safety.rig import LOCAL, MS, ROBOT, composed_of_its_own
from tests.safety.test_properties import CONFIGS, Maker, _bring_up, steps

SNAPSHOT_CONFIGS = [
    *CONFIGS,
    dataclasses.replace(ROBOT, prooftest=ProofTestPolicy.BLOCK, rearm_hold_ms=100),
    dataclasses.replace(ROBOT, prooftest=ProofTestPolicy.RECORD, require_watchdog=False),
]


def _through_text(core: SafetyCore) -> SafetyCore:
    """A snapshot of ``core`` written as the window file holds it, and the core restored."""
    return restore(json.loads(json.dumps(snapshot(core))), core.config)


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    config=st.sampled_from(SNAPSHOT_CONFIGS),
    start_in_run=st.booleans(),
    plan=steps,
    cut=st.integers(0, 40),
)
def test_a_restored_core_decides_as_the_original(
    config: SafetyConfig, start_in_run: bool, plan: list[tuple[int | None, Maker]], cut: int
) -> None:
    """SR-7.11: random inputs at random times; at a random input the core's snapshot is taken
    and restored through text. From there both cores get the same inputs and make equal
    decisions (state, causes, outputs, frames, records, refusals, deadline)."""
    now = 10_000 * MS
    core = SafetyCore(config, now)
    if start_in_run and config.prooftest is ProofTestPolicy.OFF:  # no proof test to pass
        now = _bring_up(core, now)
    restored: SafetyCore | None = None
    count = 0
    for step, make in plan:
        now = core.decision.next_deadline if step is None else now + step * MS
        for event in make(now):
            if count == cut:
                restored = _through_text(core)
                assert restored.decision == core.decision
            now = max(now, event.now)
            decision = core.handle(event)
            if restored is not None:
                assert restored.handle(event) == decision, event
            count += 1
    if restored is not None:
        assert restored.state is core.state
    note("restored" if restored is not None else "never cut")  # shown in the statistics


def test_a_snapshot_leaves_the_configuration_out_and_restore_puts_it_back() -> None:
    """SR-7.11: the configuration is the window's, in its stable form: not in the snapshot
    (the daemon's holds the output kinds' own options, no business of the core's)."""
    core = SafetyCore(ROBOT, 0)
    assert "_config" not in snapshot(core)["f"]
    assert _through_text(core).config is ROBOT


def test_a_core_with_gpio_outputs_snapshots_without_their_specifications() -> None:
    """SR-7.11, SR-7.13: the daemon gives the core the output kinds' own specifications (a GPIO
    chip and line); no machine of the core keeps them, so a core driving GPIO lines can be
    snapshot for the flight recorder and restored to decide as the original."""
    gpio = GpioSpec(name="drive", chip="gpiochip0", line=0, role=OutputRole.MOTION)
    config = dataclasses.replace(ROBOT, outputs=(gpio,))
    core = SafetyCore(config, 0)
    restored = restore(json.loads(json.dumps(snapshot(core))), config)
    assert restored.decision == core.decision
    assert "gpiochip0" not in json.dumps(snapshot(core))


def test_shared_values_stay_shared() -> None:
    """SR-7.11: a value the core holds in two places (a decision's outputs and the per-state
    cache) is one value after a restore too, as a mutation through one would show in both."""
    core = SafetyCore(ROBOT, 0)
    restored = _through_text(core)
    assert restored.decision.outputs is restored._outputs._levels_by_state[restored.state]


def test_a_restored_core_composes_the_view_of_its_own_machines() -> None:
    """SR-7.11, SR-9.4: the view of the core's machines (``face.View``, built once by the
    core) is built from them and never in a snapshot: the restored core's view holds the
    restored machines, so its cheap path and its deadlines read them and not stale copies."""
    core = _live(SafetyCore(ROBOT, 0))
    assert "_view" not in snapshot(core)["f"]
    restored = _through_text(core)
    assert composed_of_its_own(restored)


def _live(core: SafetyCore) -> SafetyCore:
    core.handle(LinkOpened(MS))
    core.handle(VscReceived(MS, FeedbackSet(85, 1)))
    core.handle(ClientConnected(MS, 1, 1000))
    core.handle(VscReceived(2 * MS, VscHeartbeat(LOCAL)))
    return core


def _damaged(change: str) -> Any:
    data = snapshot(_live(SafetyCore(ROBOT, 0)))
    fields = data["f"]
    if change == "unknown class":
        fields["_book"]["c"] = "os:system"
    elif change == "a class outside the core":
        fields["_book"]["c"] = "supervisord.record.jsonl:RecordWriter"
    elif change == "a dunder attribute":
        fields["_book"]["f"]["__class__"] = {"t": "ref", "i": 0}
    elif change == "a reference to nothing":
        fields["_book"] = {"t": "ref", "i": 999_999}
    elif change == "an unknown tag":
        fields["_book"] = {"t": "pickle", "i": 1}
    elif change == "a number used twice":
        fields["_vsc"] = copy.deepcopy(fields["_book"])
    elif change == "an enum value that does not exist":
        fields["_state"]["v"] = "flying"
    elif change == "not a core":
        data["c"] = "supervisord.safety.book:CauseBook"
    elif change == "an unhashable key":
        fields["_clients"]["f"]["_connections"]["v"] = [[{"t": "list", "i": 10_000, "v": []}, None]]
    elif change == "a configuration inside":
        fields["_config"] = None
    return data


@pytest.mark.parametrize(
    "change",
    [
        "unknown class",
        "a class outside the core",
        "a dunder attribute",
        "a reference to nothing",
        "an unknown tag",
        "a number used twice",
        "an enum value that does not exist",
        "not a core",
        "an unhashable key",
        "a configuration inside",
    ],
)
def test_a_damaged_snapshot_is_refused(change: str) -> None:
    """SR-7.11: a snapshot from another version or damaged in the file is refused with a
    reason (``SnapshotError``); nothing outside the core's own classes is ever made."""
    with pytest.raises(SnapshotError):
        restore(_damaged(change), ROBOT)


def test_a_value_no_snapshot_can_hold_is_refused() -> None:
    """SR-7.11: a core that holds something other than its own values (here an object of the
    record's) cannot be written; the daemon then counts the failure and keeps no base."""
    core = SafetyCore(ROBOT, 0)
    core._local_estop = object()  # type: ignore[assignment]
    with pytest.raises(SnapshotError):
        snapshot(core)
