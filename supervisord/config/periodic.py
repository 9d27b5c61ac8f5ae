"""The periodic tests' interval (SR-12.2; docs/configuration.md ``[maintenance]``): its
default and its range, read by the configuration and used by the daemon's schedule
(:mod:`supervisord.daemon.maintenance`), which stands above the configuration."""

from __future__ import annotations

from typing import Final

DEFAULT_INTERVAL_DAYS: Final = 30
"""Both tests once a month by default: the demand rate ISO 13849-1 (2015) asks of a category 3
or 4 safety function at PL e whose faults only a demand reveals, the most demanding level; a
robot whose risk assessment asks less sets a longer interval, one that asks more (a daily
e-stop check before each shift) a shorter. 0 turns a test's schedule off."""
INTERVAL_RANGE_DAYS: Final = (0, 3650)
