"""The fleet tier's certificates, made by the collector package's own ``srcs-fleet-pki``
(SR-13.10), run in the collector's root as its administrator would, into its default
directory (``/etc/srcs-collector/pki``, where the receiver's drop-in looks): the fleet's CA,
the collector's server certificate for its loopback address (an IP SAN:
systemd-journal-upload checks the name it connects to), and a client certificate per robot
whose CN is the robot's name. For the fleet stop (docs/fleet.md "The fleet stop"), the same
recipe makes the broker's (the collector's certificate names the broker's address too: the
broker runs beside the collector), the console's (a client certificate, CN ``console-1``),
and a certificate for ``robot-3`` signed by another CA, which the broker must refuse.

Every certificate starts a day in the past (the tool run under ``faketime``): a robot whose
clock is minutes behind (SR-13.3) must still find the collector's certificate valid."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tests.fleet.collector import Collector

COLLECTOR_ADDRESS = "127.0.0.10"
BROKER_ADDRESS = "198.18.0.1"
"""The fleet's MQTT broker, on the tier's own namespace, which the robots' agents reach over
their veths (tests/fleet/broker.py); 198.18.0.0/15 is the benchmarking range (RFC 2544)."""
CONSOLE = "console-1"
OTHER_CA = "/etc/srcs-collector/other-ca"
"""Where another CA and its robot-3 certificate are made, in the collector's root."""


def make(collector: Collector, robots: list[str]) -> None:
    """``ca.pem``, ``collector.key``/``collector.pem`` and ``ROBOT.key``/``ROBOT.pem`` in the
    collector's ``/etc/srcs-collector/pki``."""
    for command in (
        ["ca"],
        ["server", COLLECTOR_ADDRESS, BROKER_ADDRESS],
        ["robot", *robots, CONSOLE],
        ["--dir", OTHER_CA, "ca"],
        ["--dir", OTHER_CA, "robot", "robot-3"],
    ):
        collector.chroot(["faketime", "-f", "-1d", "srcs-fleet-pki", *command], check=True)
