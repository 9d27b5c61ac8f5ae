"""The ``prometheus-client`` edge: the model's families as a collector, served over HTTP.

``prometheus-client`` picks the format from the scraper's ``Accept`` header: OpenMetrics for
Prometheus (which asks for it first), the classic text format for a plain ``curl``. The
registry holds only this collector: no process metrics of the exporter's own, so that every
``srcs_*`` name means what docs/fleet.md says and nothing else is served.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator
from wsgiref.simple_server import WSGIServer

from prometheus_client import start_http_server
from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    InfoMetricFamily,
    Metric,
)
from prometheus_client.registry import Collector, CollectorRegistry
from prometheus_client.utils import floatToGoString

from supervisord.exporter.model import Family, Kind


class ModelCollector(Collector):
    """Collects ``families()`` at every scrape (the callable takes the model's lock)."""

    def __init__(self, families: Callable[[], Iterable[Family]]) -> None:
        self._families = families

    def collect(self) -> Iterator[Metric]:
        for family in self._families():
            # A family without samples would only add comment lines.
            if family.samples or family.histogram is not None:
                yield _metric(family)

    def describe(self) -> Iterator[Metric]:
        return iter(())  # no fixed description: families come and go with the connection


def _metric(family: Family) -> Metric:
    if family.histogram is not None:
        # The daemon's cumulative buckets as they are: a custom collector's histogram, since
        # the values are counted by srcsd, not observed here (docs/fleet.md).
        histogram = family.histogram
        buckets = [(_le(le), float(n)) for le, n in histogram.buckets]
        buckets.append(("+Inf", float(histogram.count)))
        return HistogramMetricFamily(
            family.name, family.help, buckets=buckets, sum_value=histogram.sum
        )
    names = tuple(dict.fromkeys(k for s in family.samples for k, _ in s.labels))
    metric: GaugeMetricFamily | CounterMetricFamily | InfoMetricFamily
    if family.kind is Kind.INFO:
        metric = InfoMetricFamily(family.name, family.help)
        for sample in family.samples:
            metric.add_metric([], dict(sample.labels))
        return metric
    if family.kind is Kind.COUNTER:
        metric = CounterMetricFamily(family.name, family.help, labels=names)
    else:
        metric = GaugeMetricFamily(family.name, family.help, labels=names)
    for sample in family.samples:
        labels = dict(sample.labels)
        metric.add_metric([labels[n] for n in names], sample.value)
    return metric


def _le(bound: float) -> str:
    """A bucket bound as prometheus-client writes its own (``0.05``, ``1.0``)."""
    text: str = floatToGoString(bound)  # type: ignore[no-untyped-call]
    return text


def serve(
    families: Callable[[], Iterable[Family]], host: str, port: int
) -> tuple[WSGIServer, threading.Thread]:
    """Serve the families on ``host:port`` (``/metrics``, any path in fact) from a thread of
    ``prometheus-client``; ``server.shutdown()`` stops it. Raises ``OSError`` if the address
    cannot be bound."""
    registry = CollectorRegistry(auto_describe=False)
    registry.register(ModelCollector(families))
    return start_http_server(port, addr=host, registry=registry)
