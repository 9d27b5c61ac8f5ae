"""The daemon's timing histograms in the exporter (docs/fleet.md "Timing
histograms"): parsed from ``status``'s ``daemon.histograms``, served as real Prometheus
histograms by prometheus-client's custom-collector API."""

from __future__ import annotations

import copy

import pytest
from prometheus_client.openmetrics.exposition import generate_latest
from prometheus_client.openmetrics.parser import text_string_to_metric_families
from prometheus_client.registry import CollectorRegistry

from supervisord.api.replies import StatusReply
from supervisord.api.wire import WireError
from supervisord.exporter.collector import ModelCollector
from supervisord.exporter.model import ExporterModel, HistogramValue, Kind, scraped_names
from tests.exporter.test_exporter_model import STATUS, status_reply

PERIODS = {"le": [0.045, 0.055, 0.1], "counts": [2, 40, 41], "sum": 2.1, "count": 42}


def _status(histograms: object) -> StatusReply:
    status = copy.deepcopy(STATUS)
    status["daemon"]["histograms"] = histograms
    return status_reply(status)


def _model(histograms: object) -> ExporterModel:
    model = ExporterModel()
    model.connected()
    model.status(_status(histograms))
    return model


def _histograms(model: ExporterModel) -> dict[str, HistogramValue]:
    return {f.name: f.histogram for f in model.families(0) if f.histogram is not None}


def test_a_status_histogram_becomes_a_histogram_family() -> None:
    """The daemon's ``vsc_heartbeat_period_seconds`` is the histogram family
    srcs_vsc_heartbeat_period_seconds with the same cumulative buckets, sum and count."""
    model = _model({"vsc_heartbeat_period_seconds": PERIODS})
    families = {f.name: f for f in model.families(0)}
    family = families["srcs_vsc_heartbeat_period_seconds"]
    assert family.kind is Kind.HISTOGRAM
    assert family.histogram == HistogramValue(((0.045, 2), (0.055, 40), (0.1, 41)), 2.1, 42)
    assert families["srcs_stop_to_off_seconds"].histogram is None  # not sent: not served


def test_histograms_go_with_the_connection() -> None:
    """Like every daemon value, the histograms are dropped when the connection ends, and a new
    daemon's smaller counts are served as they are (a counter reset, docs/fleet.md)."""
    model = _model({"stop_to_off_seconds": PERIODS})
    model.disconnected()
    assert _histograms(model) == {}
    model.connected()
    model.status(_status({"stop_to_off_seconds": {**PERIODS, "counts": [0, 0, 0], "count": 0}}))
    assert _histograms(model)["srcs_stop_to_off_seconds"].count == 0


def test_a_histogram_that_is_not_one_is_skipped() -> None:
    """Bounds that do not increase, counts that decrease or exceed ``count``, lengths that
    differ: each such histogram is skipped without raising, the others kept."""
    bad: list[object] = [
        {**PERIODS, "le": [0.1, 0.055, 0.2]},
        {**PERIODS, "counts": [5, 4, 41]},
        {**PERIODS, "counts": [2, 40, 43]},
        {**PERIODS, "counts": [2, 40]},
    ]
    for histogram in bad:
        model = _model(
            {"vsc_heartbeat_period_seconds": histogram, "user_heartbeat_period_seconds": PERIODS}
        )
        assert set(_histograms(model)) == {"srcs_user_heartbeat_period_seconds"}, histogram


@pytest.mark.parametrize(
    "histogram",
    [
        {**PERIODS, "sum": "2.1"},
        {**PERIODS, "count": True},
        {**PERIODS, "le": [0.045, None, 0.1]},
        [1, 2, 3],
        None,
    ],
)
def test_a_histogram_of_the_wrong_types_is_refused_by_the_client(histogram: object) -> None:
    """Wrong types are refused by the client's reader (the follower reconnects): the model
    never sees them."""
    with pytest.raises(WireError):
        _status({"vsc_heartbeat_period_seconds": histogram})
    with pytest.raises(WireError):
        _status("not a mapping")


def test_the_collector_serves_buckets_sum_and_count_in_openmetrics() -> None:
    """Through prometheus-client, a histogram is a ``histogram`` family in OpenMetrics with
    its ``_bucket`` series per ``le`` (``+Inf`` = count), ``_sum`` and ``_count``; every
    sample name served is one ``scraped_names`` lists."""
    model = _model({"stop_to_off_seconds": PERIODS})
    registry = CollectorRegistry(auto_describe=False)
    registry.register(ModelCollector(lambda: model.families(0)))
    text = generate_latest(registry).decode()  # type: ignore[no-untyped-call]
    families = {f.name: f for f in text_string_to_metric_families(text)}  # type: ignore[no-untyped-call]
    family = families["srcs_stop_to_off_seconds"]
    assert family.type == "histogram"
    samples = {(s.name, s.labels.get("le")): s.value for s in family.samples}
    assert samples[("srcs_stop_to_off_seconds_bucket", "0.055")] == 40
    assert samples[("srcs_stop_to_off_seconds_bucket", "+Inf")] == 42
    assert samples[("srcs_stop_to_off_seconds_sum", None)] == 2.1
    assert samples[("srcs_stop_to_off_seconds_count", None)] == 42
    names = {s.name for f in families.values() for s in f.samples}
    assert names <= set(scraped_names()), names - set(scraped_names())
