"""``srcs-exporter``: the supervisor's state and counters as Prometheus metrics (docs/fleet.md).

A client of the documented socket API (``docs/api.md``), nothing more: it never names itself
(so it is never a required client and cannot stop the robot by going away), subscribes to the
``state``, ``records`` and ``remote_status`` pushes and asks for ``status`` on a timer.

- :mod:`supervisord.exporter.model`: pure. Replies and pushes in, metric values out.
- :mod:`supervisord.exporter.follower`: the socket edge; connects, reconnects, feeds the model.
- :mod:`supervisord.exporter.collector`: the ``prometheus-client`` edge; serves the model's
  values over HTTP (OpenMetrics when the scraper asks for it).
"""
