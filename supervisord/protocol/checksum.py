"""The HRI packet checksum (manual §8.6, figure 11)."""

from __future__ import annotations

from itertools import accumulate


def fletcher16(data: bytes | bytearray | memoryview) -> int:
    """The manual's Fletcher-16 variant: both sums start at 0 and are kept mod 256.

    Returns ``sum2 << 8 | sum1``; on the wire sum1 goes first (PR-1). Over a frame it
    covers the header, type, length and payload.

    The manual's loop adds each byte to sum1 and each new sum1 to sum2. Reduction mod 256
    commutes with addition, so sum1 is the byte sum and sum2 the sum of the running sums
    (``accumulate``): the same result, computed in C rather than a Python loop (tests
    compare both; a third cheaper than weighing each byte by its distance from the end, for
    every frame that is not a repeat, SR-9.4).
    """
    sum1 = sum(data) & 0xFF
    sum2: int = sum(accumulate(data)) & 0xFF
    return sum2 << 8 | sum1
