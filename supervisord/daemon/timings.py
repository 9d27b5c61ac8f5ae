"""The loop's own timing histograms (docs/fleet.md "Timing histograms"), on its monotonic clock
since the daemon started: the heartbeats' periods, which the link port observes, and each
stop's time to off, which the loop observes as it applies a stop."""

from __future__ import annotations

from dataclasses import dataclass, field

from supervisord.histogram import HEARTBEAT_BOUNDS_NS, STOP_TO_OFF_BOUNDS_NS, Histogram


@dataclass
class Timings:
    """The loop's own timing, on its monotonic clock, since the daemon started
    (docs/fleet.md "Timing histograms")."""

    vsc_heartbeat_period: Histogram = field(default_factory=lambda: Histogram(HEARTBEAT_BOUNDS_NS))
    user_heartbeat_period: Histogram = field(default_factory=lambda: Histogram(HEARTBEAT_BOUNDS_NS))
    stop_to_off: Histogram = field(default_factory=lambda: Histogram(STOP_TO_OFF_BOUNDS_NS))
    last_vsc_heartbeat_ns: int | None = None  # the read stamp of the last VSC heartbeat
    last_user_heartbeat_ns: int | None = None  # when the last user heartbeat's write returned

    def histograms(self) -> dict[str, Histogram]:
        """By their names on the wire (docs/api.md)."""
        return {
            "vsc_heartbeat_period_seconds": self.vsc_heartbeat_period,
            "user_heartbeat_period_seconds": self.user_heartbeat_period,
            "stop_to_off_seconds": self.stop_to_off,
        }
