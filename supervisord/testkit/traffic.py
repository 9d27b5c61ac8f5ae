"""Realistic VSC serial traffic, generated deterministically from a seed.

The default mix is the VSC's (manual table 5): joystick 50 Hz, heartbeat 20 Hz, GPS 1 Hz,
plus a share of random garbage bytes between frames (a noisy RS-232 line).
"""

from __future__ import annotations

import random
from collections.abc import Iterator

from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import encode_frame
from supervisord.protocol.messages import Axis, Gps, Joystick, Message, VscHeartbeat

TICK_MS = 10
SAMPLE_GGA = "$GPGGA,123519.00,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,*69"


def vsc_messages(seconds: float, seed: int = 0) -> Iterator[Message]:
    """The messages an Operational VSC sends in ``seconds``, sticks moving at random."""
    rng = random.Random(seed)
    for tick in range(int(seconds * 1000 / TICK_MS)):
        ms = tick * TICK_MS
        if ms % 20 == 0:  # 50 Hz
            yield Joystick(
                left_x=Axis.from_value(rng.randint(-1023, 1023)),
                right_y=Axis.from_value(rng.randint(-1023, 1023)),
            )
        if ms % 50 == 0:  # 20 Hz
            yield VscHeartbeat(VscMode.OPERATIONAL)
        if ms % 1000 == 0:  # 1 Hz
            yield Gps(Gps.SOURCE_REMOTE, SAMPLE_GGA)


def vsc_stream(seconds: float, garbage: float = 0.05, seed: int = 0) -> bytes:
    """The serial bytes of ``vsc_messages`` with ``garbage`` (a fraction of all bytes) mixed in
    as random bursts between frames."""
    rng = random.Random(seed)
    out = bytearray()
    for message in vsc_messages(seconds, seed):
        frame = encode_frame(message)
        budget = len(frame) * garbage / (1 - garbage)
        burst = int(budget) + (rng.random() < budget % 1)
        out += rng.randbytes(burst)
        out += frame
    return bytes(out)
