"""The exporter's pure part: API replies and pushes in, metric values out (docs/fleet.md).

The inputs are the JSON the daemon sends, in the shapes of docs/api.md and docs/record.md
(copied from a real srcsd's pushes, trimmed to the fields that matter), read as the client
library reads them (``read_reply``, ``read_push``)."""

from __future__ import annotations

from typing import Any

import pytest

from supervisord.api.pushes import Push, read_push
from supervisord.api.replies import StatusReply, read_reply
from supervisord.api.wire import WireError
from supervisord.exporter.model import MAX_LABEL_VALUES, REMOTE_STALE_NS, ExporterModel, Kind

STATUS: dict[str, Any] = {
    "ok": True,
    "op": "status",
    "state": "RUN",
    "mono_ns": 1_000,
    "causes": [],
    "outputs": {"drive": True, "power": True},
    "heartbeat_estop": 0,
    "daemon": {
        "robot": "robot-a",
        "pid": 100,
        "version": "1.0",
        "link": {
            "description": "serial /dev/ttyUSB0",
            "open": True,
            "opens": 1,
            "open_failures": 2,
        },
        "outputs_not_acquired": [],
        "messages": 91,
        "rejections": {"bad_checksum": 3},
        "record_errors": 0,
        "records_dropped": 0,
        "rate_limited": 0,
        "internal_faults": 0,
        "clients": [],
        "connections": 1,
    },
}
REMOTE = {
    "event": "remote_status",
    "type": "remote_status",
    "battery_level": 70,
    "battery_charging": 1,
    "connection_strength_vsc": 2,
    "connection_strength_src": 1,
    "rssi_vsc": 200,
    "rssi_src": 190,
}

ESTOP_CAUSE = {"name": "vsc_estop", "severity": "stop", "active": True, "latched": True}
MODE_CAUSE = {"name": "vsc_mode:local", "severity": "hold", "active": True, "latched": False}

STOP_RECORD: dict[str, Any] = {
    "event": "record",
    "seq": 7,
    "mono_ns": 2_000,
    "utc": "2026-03-01T12:00:07.000000+00:00",
    "kind": "state_change",
    "from": "RUN",
    "to": "STOPPED",
    "causes": [ESTOP_CAUSE, MODE_CAUSE],
    "changes": [
        {"name": "vsc_estop", "change": "raised"},
        {"name": "vsc_mode:local", "change": "raised"},
    ],
    "trigger": {"event": "vsc_received"},
}
REARM_RECORD: dict[str, Any] = {
    "event": "record",
    "seq": 9,
    "mono_ns": 3_000,
    "utc": "2026-03-01T12:00:09.000000+00:00",
    "kind": "state_change",
    "from": "STOPPED",
    "to": "RUN",
    "causes": [],
    "changes": [
        {"name": "vsc_mode:local", "change": "cleared"},
        {"name": "vsc_estop", "change": "released"},
    ],
    "trigger": {"event": "vsc_received"},
    "rearm": {"kind": "takeover"},
}


def status_reply(obj: dict[str, Any]) -> StatusReply:
    """``obj`` as the client reads it."""
    reply = read_reply(obj)
    assert isinstance(reply, StatusReply)
    return reply


def pushed(obj: dict[str, Any]) -> Push:
    return read_push(obj)


def state(name: str, mono_ns: int, *causes: dict[str, Any]) -> Push:
    """A ``state`` push."""
    return pushed(
        {"event": "state", "state": name, "mono_ns": mono_ns, "causes": list(causes),
         "outputs": {}, "heartbeat_estop": 1}
    )  # fmt: skip


def values(
    model: ExporterModel, now_ns: int = 0
) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample as ``{(family, labels): value}``."""
    return {
        (family.name, sample.labels): sample.value
        for family in model.families(now_ns)
        for sample in family.samples
    }


def names(model: ExporterModel) -> set[str]:
    return {name for name, _ in values(model)}


def connected(status: dict[str, Any] = STATUS) -> ExporterModel:
    model = ExporterModel()
    model.connected()
    model.status(status_reply(status))
    return model


def test_status_reply_gives_state_outputs_link_and_counters() -> None:
    """A status reply sets srcs_up, one srcs_state series per state, outputs, link and counters."""
    v = values(connected())
    assert v[("srcs_up", ())] == 1
    assert v[("srcs_state", (("state", "RUN"),))] == 1
    assert v[("srcs_state", (("state", "STOPPED"),))] == 0
    assert v[("srcs_output_on", (("output", "drive"),))] == 1
    assert v[("srcs_link_up", ())] == 1
    assert v[("srcs_link_open_failures", ())] == 2
    assert v[("srcs_messages", ())] == 91
    assert v[("srcs_rejections", (("reason", "bad_checksum"),))] == 3
    assert v[("srcs_record_errors", ())] == 0
    assert v[("srcs_daemon", (("robot", "robot-a"),))] == 1


def test_disconnect_drops_every_daemon_value_but_keeps_own_counters() -> None:
    """After the connection ends: srcs_up 0, no state, cause, link or remote value; the
    exporter's own counters (stops seen) stay."""
    model = connected()
    model.push(pushed(STOP_RECORD), 0)
    model.push(pushed(REMOTE), 0)
    model.disconnected()
    v = values(model)
    assert v[("srcs_up", ())] == 0
    assert v[("srcs_stops", (("cause", "vsc_estop"),))] == 1
    daemon_families = {"srcs_state", "srcs_cause_active", "srcs_link_up", "srcs_messages"}
    assert not daemon_families & names(model)
    assert "srcs_remote_battery_percent" not in names(model)


def test_stop_record_counts_each_stop_cause_raised_with_it() -> None:
    """A RUN -> STOPPED record counts its raised stop causes, not its hold causes."""
    model = connected()
    model.push(pushed(STOP_RECORD), 0)
    v = values(model)
    assert v[("srcs_stops", (("cause", "vsc_estop"),))] == 1
    assert ("srcs_stops", (("cause", "vsc_mode:local"),)) not in v
    assert v[("srcs_causes_raised", (("cause", "vsc_mode:local"),))] == 1
    assert v[("srcs_state_transitions", (("from_state", "RUN"), ("to_state", "STOPPED")))] == 1


def test_rearm_record_counts_released_causes_by_kind() -> None:
    """A STOPPED -> RUN record counts a re-arm per released cause, labelled with its kind."""
    model = connected()
    model.push(pushed(STOP_RECORD), 0)
    model.push(pushed(REARM_RECORD), 0)
    v = values(model)
    assert v[("srcs_rearms", (("cause", "vsc_estop"), ("kind", "takeover")))] == 1


def test_a_gap_in_sequence_numbers_is_counted_as_missed() -> None:
    """Records 7 then 9 (8 was written while the exporter was away): one missed, two seen."""
    model = connected()
    model.push(pushed(STOP_RECORD), 0)
    model.disconnected()
    model.connected()
    model.push(pushed(REARM_RECORD), 0)
    v = values(model)
    assert v[("srcs_records_missed", ())] == 1
    assert v[("srcs_records_seen", ())] == 2
    assert v[("srcs_record_last_seq", ())] == 9


def test_a_sequence_that_starts_again_is_no_gap() -> None:
    """A record numbered below the last one (a new record file) counts, with nothing missed."""
    model = connected()
    model.push(pushed(REARM_RECORD), 0)
    model.push(pushed({**STOP_RECORD, "seq": 1}), 0)
    v = values(model)
    assert v[("srcs_records_missed", ())] == 0
    assert v[("srcs_record_last_seq", ())] == 1
    assert v[("srcs_stops", (("cause", "vsc_estop"),))] == 1


def test_state_push_sets_cause_flags_and_keeps_seen_causes_at_zero() -> None:
    """A state push sets active/latched; a cause gone from the list reads 0, not absent."""
    model = connected()
    model.push(state("STOPPED", 2_000, ESTOP_CAUSE), 0)
    labels = (("cause", "vsc_estop"), ("severity", "stop"))
    assert values(model)[("srcs_cause_latched", labels)] == 1
    model.push(state("RUN", 3_000), 0)
    v = values(model)
    assert v[("srcs_cause_latched", labels)] == 0
    assert v[("srcs_cause_active", labels)] == 0
    assert v[("srcs_state", (("state", "RUN"),))] == 1


def test_an_older_state_push_does_not_turn_the_state_back() -> None:
    """A push decided before the status reply already applied is ignored for the state."""
    model = connected({**STATUS, "mono_ns": 5_000})
    model.push(state("STOPPED", 4_000), 0)
    assert values(model)[("srcs_state", (("state", "RUN"),))] == 1


def test_remote_status_is_exported_only_while_fresh() -> None:
    """Battery, link strength and RSSI come from the last remote-status push, and go once it
    is older than REMOTE_STALE_NS (the VSC never clears them, manual §8.3.4)."""
    model = connected()
    model.push(pushed(REMOTE), 10)
    v = values(model, 10 + 1_000_000_000)
    assert v[("srcs_remote_battery_percent", ())] == 70
    assert v[("srcs_remote_link_strength", (("seen_by", "remote"),))] == 1
    assert v[("srcs_remote_rssi", (("seen_by", "vsc"),))] == 200
    assert v[("srcs_remote_status_age_seconds", ())] == 1.0
    assert "srcs_remote_battery_percent" not in {
        name for name, _ in values(model, 11 + REMOTE_STALE_NS)
    }


def test_estop_available_is_a_gauge_from_the_status_reply() -> None:
    """SR-8.11: ``srcs_estop_available`` is 1 or 0 as the last status reply's
    ``estop_available`` says, in any state; absent without one (an older daemon, a reply
    without the field) and once the connection ends."""
    gauge = ("srcs_estop_available", ())
    model = connected()
    assert gauge not in values(model)
    available = {**STATUS, "estop_available": {"available": True, "missing": []}}
    model.status(status_reply(available))
    assert values(model)[gauge] == 1
    low = ["the remote's battery is 10 %, below 20 %"]
    model.status(status_reply({**STATUS, "estop_available": {"available": False, "missing": low}}))
    assert values(model)[gauge] == 0
    model.push(state("STOPPED", 5_000), 0)
    assert values(model)[gauge] == 0  # a push carries no estop_available: the reply's stays
    model.status(status_reply(STATUS))
    assert gauge not in values(model)
    model.status(status_reply(available))
    model.disconnected()
    assert gauge not in values(model)


@pytest.mark.parametrize(
    "junk",
    [
        {"event": "state", "state": "RUN", "mono_ns": "soon", "causes": 3},
        {"event": "record", "seq": "x", "from": 1, "to": None, "changes": [1, None, "a"]},
        {"event": "remote_status", "battery_level": "full"},
        {},
    ],
)
def test_garbage_from_the_daemon_never_reaches_the_model(junk: dict[str, Any]) -> None:
    """Wrong types and missing fields are refused by the client's reader (the follower then
    reconnects), so the model never sees them."""
    with pytest.raises(WireError):
        read_push(junk)


def test_what_the_model_does_not_know_changes_nothing() -> None:
    """A push of an unknown event changes nothing and raises nothing; a state outside SR-1's
    three is refused by the client's reader (the shared vocabulary is strict: the model never
    sees it)."""
    model = connected()
    before = values(model)
    with pytest.raises(WireError, match="not a State"):
        state("FLYING", 9_000)
    model.push(pushed({"event": "teleport", "to": "mars"}), 0)
    assert values(model) == before


def test_cause_labels_are_capped() -> None:
    """Past MAX_LABEL_VALUES distinct causes, new names are counted under "other"."""
    model = connected()
    for i in range(MAX_LABEL_VALUES + 5):
        cause = {"name": f"client_estop:c{i}", "severity": "stop", "active": True}
        record = {
            **STOP_RECORD,
            "seq": i + 1,
            "from": "STOPPED",
            "to": "STOPPED",
            "causes": [{**cause, "latched": True}],
            "changes": [{"name": cause["name"], "change": "raised"}],
        }
        model.push(pushed(record), 0)
    raised = [labels for name, labels in values(model) if name == "srcs_causes_raised"]
    assert len(raised) == MAX_LABEL_VALUES + 1
    assert values(model)[("srcs_causes_raised", (("cause", "other"),))] == 5


def test_counter_families_are_typed_as_counters() -> None:
    """srcs_stops and the daemon's counters are counters (Prometheus's rate() handles resets)."""
    kinds = {f.name: f.kind for f in connected().families(0)}
    assert kinds["srcs_stops"] is Kind.COUNTER
    assert kinds["srcs_messages"] is Kind.COUNTER
    assert kinds["srcs_state"] is Kind.GAUGE


def test_the_periodic_tests_are_an_age_and_an_overdue_gauge() -> None:
    """SR-12.2: each periodic test of ``status``'s ``daemon.maintenance`` is two gauges,
    labelled with the test: the last pass's age in seconds (absent when it never passed)
    and 1 while overdue; a test the reply does not name or an unknown test gives no sample,
    a wrong type is refused by the client's reader (the model never sees it), and nothing
    stays once the connection ends."""
    age = ("srcs_test_last_pass_age_seconds", (("test", "stoptest"),))
    overdue = ("srcs_test_overdue", (("test", "stoptest"),))
    proof_overdue = ("srcs_test_overdue", (("test", "prooftest"),))
    model = connected()
    assert overdue not in values(model)
    schedule = {
        "stoptest": {"interval_days": 30, "last_pass_age_s": 86_400.5, "overdue": False},
        "prooftest": {"interval_days": 30, "last_pass_age_s": None, "overdue": True},
        "novel": {"interval_days": 1, "last_pass_age_s": 1.0, "overdue": True},
    }
    model.status(status_reply({**STATUS, "daemon": {**STATUS["daemon"], "maintenance": schedule}}))
    v = values(model)
    assert v[age] == 86_400.5
    assert v[overdue] == 0
    assert v[proof_overdue] == 1
    assert ("srcs_test_last_pass_age_seconds", (("test", "prooftest"),)) not in v
    assert not [k for k in v if ("test", "novel") in k[1]]
    only_proof = {"prooftest": schedule["prooftest"]}
    model.status(
        status_reply({**STATUS, "daemon": {**STATUS["daemon"], "maintenance": only_proof}})
    )
    assert age not in values(model)
    assert overdue not in values(model)
    assert values(model)[proof_overdue] == 1
    broken = {"stoptest": {"interval_days": 30, "last_pass_age_s": "a day", "overdue": "yes"}}
    with pytest.raises(WireError):
        status_reply({**STATUS, "daemon": {**STATUS["daemon"], "maintenance": broken}})
    model.status(status_reply({**STATUS, "daemon": {**STATUS["daemon"], "maintenance": schedule}}))
    model.disconnected()
    assert overdue not in values(model)


def test_the_memory_lock_is_a_gauge_from_the_status_reply() -> None:
    """SR-9.6: ``srcs_memory_locked`` is 1 or 0 as the status reply's
    ``daemon.memory_locked`` says; absent from a daemon older than the lock."""
    gauge = ("srcs_memory_locked", ())
    assert gauge not in values(connected())
    for locked, value in ((True, 1), (False, 0)):
        reply = {**STATUS, "daemon": {**STATUS["daemon"], "memory_locked": locked}}
        assert values(connected(reply))[gauge] == value
