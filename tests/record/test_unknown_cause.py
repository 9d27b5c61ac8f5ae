"""A cause kind this client does not know (docs/api.md "Cause kinds a client does not know"):
a newer daemon's record, or an old record file's, read by a client keeps it as written."""

from __future__ import annotations

import json
from typing import Any

from supervisord.api.pushes import RecordPush, read_push
from supervisord.exporter.model import ExporterModel
from supervisord.record.stop import read_record
from supervisord.vocabulary import CauseKind, UnknownCause, UnknownCauseKind

LINE: dict[str, Any] = {
    "seq": 7,
    "mono_ns": 5,
    "utc": "2026-03-01T12:00:07.000000+00:00",
    "from": "RUN",
    "to": "STOPPED",
    "causes": [
        {"name": "lidar_blind:front", "severity": "stop", "active": True, "latched": True,
         "raised_ns": 5, "cleared_ns": None, "details": {"reason": "dazzled"}},
        {"name": "vsc_estop:odd", "severity": "stop", "active": False, "latched": True,
         "raised_ns": 1, "cleared_ns": 2, "details": {}},
    ],
    "changes": [{"name": "lidar_blind:front", "change": "raised"}],
    "trigger": {"event": "tick"},
}  # fmt: skip
"""A stop by a cause kind this version lacks, and a known kind with a subject it never has."""


def test_a_record_with_an_unknown_cause_kind_reads_and_writes_back_as_it_came() -> None:
    """SR-7.1, SR-8.7: a record naming a cause kind this client does not know is read, not
    refused: the cause keeps its text (kind and subject), equals no known kind, and the
    record writes back the same JSON."""
    record = read_record(json.loads(json.dumps(LINE)))
    blind, odd = record.causes
    assert blind.name == UnknownCause(UnknownCauseKind("lidar_blind"), "front")
    assert blind.name.name == "lidar_blind:front"
    assert odd.name == UnknownCause(UnknownCauseKind("vsc_estop"), "odd")
    assert odd.kind is not CauseKind.VSC_ESTOP
    assert record.json() == LINE


def test_the_exporter_counts_an_unknown_cause_under_its_text() -> None:
    """SR-7.1: the stop a newer daemon's cause made is counted under that cause's text."""
    push = read_push({"event": "record", **LINE})
    assert isinstance(push, RecordPush)
    model = ExporterModel()
    model.connected()
    model.push(push, 0)
    stops = {
        s.labels: s.value for f in model.families(0) if f.name == "srcs_stops" for s in f.samples
    }
    assert stops == {(("cause", "lidar_blind:front"),): 1.0}
