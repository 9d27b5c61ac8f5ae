"""The fleet tier's certificates, made by the collector package's own ``srcs-fleet-pki``
(SR-13.10), run in the collector's root as its administrator would, into its default
directory (``/etc/srcs-collector/pki``, where the receiver's drop-in looks): the fleet's CA,
the collector's server certificate for its loopback address (an IP SAN:
systemd-journal-upload checks the name it connects to), and a client certificate per robot
whose CN is the robot's name.

Every certificate starts a day in the past (the tool run under ``faketime``): a robot whose
clock is minutes behind (SR-13.3) must still find the collector's certificate valid."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tests.fleet.collector import Collector

COLLECTOR_ADDRESS = "127.0.0.10"


def make(collector: Collector, robots: list[str]) -> None:
    """``ca.pem``, ``collector.key``/``collector.pem`` and ``ROBOT.key``/``ROBOT.pem`` in the
    collector's ``/etc/srcs-collector/pki``."""
    for command in (["ca"], ["server", COLLECTOR_ADDRESS], ["robot", *robots]):
        collector.chroot(["faketime", "-f", "-1d", "srcs-fleet-pki", *command], check=True)
