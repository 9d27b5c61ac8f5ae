"""The HRI packet checksum (manual §8.6, figure 11)."""

from __future__ import annotations

from operator import mul


def fletcher16(data: bytes | bytearray | memoryview) -> int:
    """The manual's Fletcher-16 variant: both sums start at 0 and are kept mod 256.

    Returns ``sum2 << 8 | sum1``; on the wire sum1 goes first (PR-1). Over a frame it
    covers the header, type, length and payload.

    The manual's loop adds each byte to sum1 and each new sum1 to sum2. Reduction mod 256
    commutes with addition, so sum1 is the byte sum and sum2 weighs byte i of n by n - i:
    the same result, computed in C rather than a Python loop (tests compare both).
    """
    sum1 = sum(data) & 0xFF
    sum2: int = sum(map(mul, data, range(len(data), 0, -1))) & 0xFF
    return sum2 << 8 | sum1
