"""Decoder throughput on a realistic VSC stream.

Run: ``./dev bench`` (or ``.venv/bin/python -m bench.decoder [seconds-of-traffic]``).
The stream is the VSC's default mix (joystick 50 Hz, heartbeat 20 Hz, GPS 1 Hz) with 5 %
random garbage, fed in 64-byte reads as a serial port delivers it. Prints MB/s and the
multiple of the 115200-baud line rate (8N1: 10 bits a byte, 11,520 bytes/s).
"""

from __future__ import annotations

import platform
import sys
import time

from supervisord.protocol.framing import FrameDecoder, Rejection
from supervisord.testkit.traffic import vsc_stream

LINE_RATE = 115200 / 10  # bytes per second on the wire
READ_SIZE = 64
RUNS = 5


def decode_once(stream: bytes) -> tuple[float, int, int]:
    """Seconds to decode ``stream`` in READ_SIZE pieces, messages and rejections seen."""
    decoder = FrameDecoder()
    messages = rejections = 0
    start = time.perf_counter()
    for at in range(0, len(stream), READ_SIZE):
        for event in decoder.feed(stream[at : at + READ_SIZE]):
            if isinstance(event, Rejection):
                rejections += 1
            else:
                messages += 1
    return time.perf_counter() - start, messages, rejections


def main() -> None:
    traffic_seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 120.0
    stream = vsc_stream(traffic_seconds, garbage=0.05, seed=1)
    best, messages, rejections = min(decode_once(stream) for _ in range(RUNS))
    rate = len(stream) / best
    real_rate = len(stream) / traffic_seconds
    print(f"machine: {platform.machine()}, Python {platform.python_version()}")
    print(
        f"stream: {traffic_seconds:.0f} s of VSC traffic, {len(stream)} bytes, "
        f"{messages} messages, {rejections} rejections (5 % garbage)"
    )
    print(f"decoder: {rate / 1e6:.2f} MB/s (best of {RUNS}, {READ_SIZE}-byte reads)")
    print(f"         {rate / LINE_RATE:.0f} x the 115200-baud line rate")
    print(f"         {100 * real_rate / rate:.3f} % of one core at the VSC's real traffic rate")


if __name__ == "__main__":
    main()
